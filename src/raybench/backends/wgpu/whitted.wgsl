// kernels/whitted.py: Whitted shading, a pixel per invocation, from a bounded
// stack of pending rays; the same formulas in the same order (the Python
// docstrings say why each holds). find() is brute.wgsl's or traverse.wgsl's.

// Each sphere's material: lighting.materials_array's columns as a row.
struct Material {
    specular: f32,
    shininess: f32,
    reflect: f32,
    transmit: f32,
    ior: f32,
}

struct Light {
    position: vec4<f32>,   // xyz, radius (0: a point light)
    power: vec4<f32>,      // colour times intensity, pad
}

// lighting.Shading, in one uniform buffer (compute.py's lighting_uniform).
struct Lighting {
    ambient: vec4<f32>,
    background: vec4<f32>,   // rgb, and 1 for the thesis's gradient
    sizes: vec4<u32>,        // lights, shadow samples, depth, pad
    lights: array<Light, MAX_LIGHTS>,
    pattern: array<vec4<f32>, MAX_SAMPLES>,
}

@group(0) @binding(7) var<storage, read> materials: array<Material>;
@group(0) @binding(8) var<uniform> lighting: Lighting;
// The rays cast, by kind (primary, shadow, reflection, refraction).
@group(0) @binding(9) var<storage, read_write> rays: array<atomic<u32>, 4>;

const RAY_STACK: u32 = WHITTED_RAY_STACK;
const CUTOFF: f32 = WHITTED_CUTOFF;
const OFFSET: f32 = WHITTED_OFFSET;
// Keeps Fresnel's quotients finite where both cosines are 0.
const FRESNEL_TINY: f32 = 1e-30;
const PRIMARY: i32 = 0;
const REFLECTION: i32 = 2;
const REFRACTION: i32 = 3;

struct Ray {
    o: vec3<f32>,
    d: vec3<f32>,
    w: vec3<f32>,
    slack: f32,
    depth: u32,
    kind: i32,
    own: i32,
    inside: bool,
}

// The hit's diffuse (ambient and Lambert) and specular (Phong) light, and
// the shadow rays cast (in .w of the second).
struct Local {
    diffuse: vec3<f32>,
    specular: vec3<f32>,
    shadows: u32,
}

fn local_light(p: vec3<f32>, n: vec3<f32>, v: vec3<f32>, i: i32, inside: bool) -> Local {
    let s = spheres[i];
    var dr = lighting.ambient.x * s.red;
    var dg = lighting.ambient.y * s.green;
    var db = lighting.ambient.z * s.blue;
    var sr = 0.0;
    var sg = 0.0;
    var sb = 0.0;
    let ks = materials[i].specular;
    let shininess = materials[i].shininess;
    var shadows = 0u;
    for (var light = 0u; light < lighting.sizes.x; light = light + 1u) {
        let l = lighting.lights[light];
        let radius = l.position.w;
        var samples = 1u;
        if (radius > 0.0) {
            samples = lighting.sizes.y;
        }
        let share = 1.0 / f32(samples);
        for (var k = 0u; k < samples; k = k + 1u) {
            let q = lighting.pattern[k];
            var lx = l.position.x + radius * q.x - p.x;
            var ly = l.position.y + radius * q.y - p.y;
            var lz = l.position.z + radius * q.z - p.z;
            let dist = sqrt(lx * lx + ly * ly + lz * lz);
            if (dist <= 0.0) {
                continue;
            }
            lx = lx / dist;
            ly = ly / dist;
            lz = lz / dist;
            let facing = n.x * lx + n.y * ly + n.z * lz;
            if (facing <= 0.0) {
                continue;
            }
            let cr = l.power.x * share;
            let cg = l.power.y * share;
            let cb = l.power.z * share;
            if (max(cr, max(cg, cb)) <= 0.0) {  // a dark light adds nothing, blocked or not
                continue;
            }
            shadows = shadows + 1u;
            if (find(p, vec3<f32>(lx, ly, lz), dist, true, i, inside).index >= 0) {
                continue;
            }
            dr = dr + cr * s.red * facing;
            dg = dg + cg * s.green * facing;
            db = db + cb * s.blue * facing;
            if (ks > 0.0) {
                let rv = 2.0 * facing * (n.x * v.x + n.y * v.y + n.z * v.z) - (lx * v.x + ly * v.y + lz * v.z);
                if (rv > 0.0) {
                    let glint = ks * pow(rv, shininess);
                    sr = sr + cr * glint;
                    sg = sg + cg * glint;
                    sb = sb + cb * glint;
                }
            }
        }
    }
    return Local(vec3<f32>(dr, dg, db), vec3<f32>(sr, sg, sb), shadows);
}

// Snell and the exact dielectric Fresnel equations (whitted.fresnel):
// reflectance, cos_t, eta.
fn fresnel(cos_i: f32, inside: bool, ior: f32) -> vec3<f32> {
    var eta = 1.0 / ior;
    if (inside) {
        eta = ior;
    }
    let k = 1.0 - eta * eta * (1.0 - cos_i * cos_i);
    if (k < 0.0) {  // total internal reflection
        return vec3<f32>(1.0, 0.0, eta);
    }
    let cos_t = sqrt(k);
    let a = eta * cos_i;
    let rs = (a - cos_t) / max(a + cos_t, FRESNEL_TINY);
    let b = eta * cos_t;
    let rp = (cos_i - b) / max(cos_i + b, FRESNEL_TINY);
    return vec3<f32>(0.5 * (rs * rs + rp * rp), cos_t, eta);
}

// whitted.prune: which children to cast, and the slack each takes.
struct Pruned {
    reflect: bool,
    transmit: bool,
    slack: f32,
}

fn prune(wmax: f32, kr: f32, kt: f32, slack_in: f32) -> Pruned {
    let mr = wmax * kr;
    let mt = wmax * kt;
    var slack = slack_in;
    var drop_r = false;
    var drop_t = false;
    if (mt <= mr) {
        if (mt <= slack) {
            drop_t = true;
            slack = slack - mt;
        }
        if (mr <= slack) {
            drop_r = true;
            slack = slack - mr;
        }
    } else {
        if (mr <= slack) {
            drop_r = true;
            slack = slack - mr;
        }
        if (mt <= slack) {
            drop_t = true;
            slack = slack - mt;
        }
    }
    if (!drop_r && !drop_t) {
        slack = slack * 0.5;
    }
    return Pruned(!drop_r, !drop_t, slack);
}

// The pixel's colour and primary hit; counts: its rays by kind.
struct Shaded {
    color: vec3<f32>,
    hit: i32,
    counts: vec4<u32>,
}

fn whitted_pixel(x: u32, y: u32) -> Shaded {
    var background = lighting.background.xyz;
    if (lighting.background.w > 0.0) {
        background = shade_miss(f32(x), f32(y));
    }
    let lit = lighting.sizes.x > 0u;
    var color = vec3<f32>(0.0, 0.0, 0.0);
    var first_hit = -1;
    var counts = vec4<u32>(0u, 0u, 0u, 0u);
    var pending: array<Ray, RAY_STACK>;
    pending[0] = Ray(frame.origin.xyz, primary_ray(x, y), vec3<f32>(1.0, 1.0, 1.0), CUTOFF, 0u, PRIMARY, -1, false);
    var top = 1u;
    while (top > 0u) {
        top = top - 1u;
        let ray = pending[top];
        let dx = ray.d.x;
        let dy = ray.d.y;
        let dz = ray.d.z;
        if (ray.kind == PRIMARY) {
            counts.x = counts.x + 1u;
        } else if (ray.kind == REFLECTION) {
            counts.z = counts.z + 1u;
        } else {
            counts.w = counts.w + 1u;
        }
        let found = find(ray.o, ray.d, FAR, false, ray.own, ray.inside);
        let i = found.index;
        if (ray.kind == PRIMARY) {
            first_hit = i;
        }
        if (i < 0) {
            color = color + ray.w * background;
            continue;
        }
        let s = spheres[i];
        let t = found.t;
        let px = ray.o.x + t * dx;
        let py = ray.o.y + t * dy;
        let pz = ray.o.z + t * dz;
        let inv_r = 1.0 / s.r;
        var nx = (px - s.cx) * inv_r;
        var ny = (py - s.cy) * inv_r;
        var nz = (pz - s.cz) * inv_r;
        let inv_n = 1.0 / sqrt(nx * nx + ny * ny + nz * nz);
        nx = nx * inv_n;
        ny = ny * inv_n;
        nz = nz * inv_n;
        var cos_i = -(nx * dx + ny * dy + nz * dz);
        let inside = cos_i < 0.0;  // the ray meets the sphere from within
        if (inside) {
            nx = -nx;
            ny = -ny;
            nz = -nz;
            cos_i = -cos_i;
        }
        let m = materials[i];
        var kr = m.reflect;
        var kt = m.transmit;
        let keep = 1.0 - kr - kt;
        if (lit) {
            // shadow rays only from a surface whose own light can show (whitted.shows)
            if (m.specular > 0.0 || keep * max(s.red, max(s.green, s.blue)) > 0.0) {
                let l = local_light(vec3<f32>(px, py, pz), vec3<f32>(nx, ny, nz), vec3<f32>(-dx, -dy, -dz), i, inside);
                counts.y = counts.y + l.shadows;
                color = color + ray.w * (keep * l.diffuse + l.specular);
            }
        } else {
            color = color + ray.w * (keep * shade_hit(s, found.d));
        }
        if (ray.depth >= lighting.sizes.z || (kr <= 0.0 && kt <= 0.0)) {
            continue;
        }
        // whitted.branches
        var tdir = vec3<f32>(0.0, 0.0, 0.0);
        if (kt > 0.0) {
            let f = fresnel(cos_i, inside, m.ior);
            kr = kr + kt * f.x;
            kt = kt * (1.0 - f.x);
            let eta = f.z;
            let a = eta * cos_i - f.y;
            tdir = vec3<f32>(eta * dx + a * nx, eta * dy + a * ny, eta * dz + a * nz);
        }
        let pruned = prune(max(ray.w.x, max(ray.w.y, ray.w.z)), kr, kt, ray.slack);
        let offset = OFFSET * (abs(px) + abs(py) + abs(pz));
        if (pruned.transmit) {
            // it goes through the surface: from outside into the sphere, or out of it
            pending[top] = Ray(
                vec3<f32>(px - offset * nx, py - offset * ny, pz - offset * nz),
                tdir, ray.w * kt, pruned.slack, ray.depth + 1u, REFRACTION, i, !inside);
            top = top + 1u;
        }
        if (pruned.reflect) {
            let two_cos = 2.0 * cos_i;
            pending[top] = Ray(
                vec3<f32>(px + offset * nx, py + offset * ny, pz + offset * nz),
                vec3<f32>(dx + two_cos * nx, dy + two_cos * ny, dz + two_cos * nz),
                ray.w * kr, pruned.slack, ray.depth + 1u, REFLECTION, i, inside);
            top = top + 1u;
        }
    }
    return Shaded(color, first_hit, counts);
}

var<workgroup> tally: array<atomic<u32>, 4>;

// One invocation per pixel; the workgroup sums its rays, then one atomic a
// kind adds them to the frame's (barriers in uniform control flow: every
// invocation reaches them, those off the image with nothing to add).
@compute @workgroup_size(WORKGROUP_X, WORKGROUP_Y)
fn main_whitted(@builtin(global_invocation_id) id: vec3<u32>, @builtin(local_invocation_index) me: u32) {
    // zeroed here, not trusted to be: on lavapipe a workgroup found the last one's sums
    if (me < 4u) {
        atomicStore(&tally[me], 0u);
    }
    workgroupBarrier();
    if (id.x < frame.width && id.y < frame.height) {
        let shaded = whitted_pixel(id.x, id.y);
        let c = shaded.color;
        let bytes = vec3<f32>(to_byte(c.x), to_byte(c.y), to_byte(c.z));
        textureStore(image, vec2<i32>(i32(id.x), i32(id.y)), vec4<f32>(bytes / 255.0, 1.0));
        hits[id.y * frame.width + id.x] = shaded.hit;
        atomicAdd(&tally[0], shaded.counts.x);
        atomicAdd(&tally[1], shaded.counts.y);
        atomicAdd(&tally[2], shaded.counts.z);
        atomicAdd(&tally[3], shaded.counts.w);
    }
    workgroupBarrier();
    if (me < 4u) {
        atomicAdd(&rays[me], atomicLoad(&tally[me]));
    }
}
