// kernels/whitted.py: Whitted shading, a pixel per invocation, from a bounded
// stack of pending rays; the same formulas in the same order (the Python
// docstrings say why each holds). find() is brute.wgsl's or traverse.wgsl's;
// a hit's surface and rim are sphere.wgsl's.

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

// whitted.light_samples: shadow rays to one light.
fn samples_of(light: u32) -> u32 {
    if (lighting.lights[light].position.w > 0.0) {
        return lighting.sizes.y;
    }
    return 1u;
}

// whitted.toward: a shadow ray to sample s of a light; facing 0 where none is cast.
struct Toward {
    l: vec3<f32>,
    dist: f32,
    facing: f32,
    c: vec3<f32>,
}

fn toward(p: vec3<f32>, n: vec3<f32>, light: u32, s: u32, share: f32) -> Toward {
    let lamp = lighting.lights[light];
    let radius = lamp.position.w;
    let q = lighting.pattern[s];
    var lx = lamp.position.x + radius * q.x - p.x;
    var ly = lamp.position.y + radius * q.y - p.y;
    var lz = lamp.position.z + radius * q.z - p.z;
    let dist = sqrt(lx * lx + ly * ly + lz * lz);
    let c = vec3<f32>(lamp.power.x * share, lamp.power.y * share, lamp.power.z * share);
    if (dist <= 0.0 || max(c.x, max(c.y, c.z)) <= 0.0) {  // at the light, or a dark light: it adds nothing
        return Toward(vec3<f32>(lx, ly, lz), dist, 0.0, c);
    }
    lx = lx / dist;
    ly = ly / dist;
    lz = lz / dist;
    let facing = max(n.x * lx + n.y * ly + n.z * lz, 0.0);
    return Toward(vec3<f32>(lx, ly, lz), dist, facing, c);
}

// whitted.lifted: where a hit's shadow rays start, OFFSET of its magnitude
// along the normal on the viewer's side (a coplanar neighbour triangle would
// block them at t ~ 0 otherwise).
fn lifted(p: vec3<f32>, n: vec3<f32>) -> vec3<f32> {
    return p + (OFFSET * (abs(p.x) + abs(p.y) + abs(p.z))) * n;
}

// whitted.glint: Phong's highlight of one light sample.
fn glint(ks: f32, shininess: f32, facing: f32, n: vec3<f32>, v: vec3<f32>, l: vec3<f32>) -> f32 {
    if (ks > 0.0) {
        let rv = 2.0 * facing * (n.x * v.x + n.y * v.y + n.z * v.z) - (l.x * v.x + l.y * v.y + l.z * v.z);
        if (rv > 0.0) {
            return ks * pow(rv, shininess);
        }
    }
    return 0.0;
}

fn local_light(hit_p: vec3<f32>, n: vec3<f32>, v: vec3<f32>, i: i32, inside: bool) -> Local {
    let p = lifted(hit_p, n);
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
        let samples = samples_of(light);
        let share = 1.0 / f32(samples);
        for (var k = 0u; k < samples; k = k + 1u) {
            let to = toward(p, n, light, k, share);
            if (to.facing <= 0.0) {
                continue;
            }
            shadows = shadows + 1u;
            if (find(p, to.l, to.dist, true, i, inside).index >= 0) {
                continue;
            }
            dr = dr + to.c.x * s.red * to.facing;
            dg = dg + to.c.y * s.green * to.facing;
            db = db + to.c.z * s.blue * to.facing;
            let g = glint(ks, shininess, to.facing, n, v, to.l);
            sr = sr + to.c.x * g;
            sg = sg + to.c.y * g;
            sb = sb + to.c.z * g;
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

// whitted.shows: only then are the hit's shadow rays cast.
fn shows(s: Sphere, m: Material, keep: f32) -> bool {
    return m.specular > 0.0 || keep * max(s.red, max(s.green, s.blue)) > 0.0;
}

// whitted.branches: a hit's two children (kr > 0 or kt > 0).
struct Branches {
    kr: f32,
    kt: f32,
    tdir: vec3<f32>,
    pruned: Pruned,
}

fn branches(d: vec3<f32>, hit: Surface, kr_in: f32, kt_in: f32, ior: f32, w: vec3<f32>, slack: f32) -> Branches {
    var kr = kr_in;
    var kt = kt_in;
    var tdir = vec3<f32>(0.0, 0.0, 0.0);
    if (kt > 0.0) {
        let f = fresnel(hit.cos_i, hit.inside, ior);
        kr = kr + kt * f.x;
        kt = kt * (1.0 - f.x);
        let eta = f.z;
        let a = eta * hit.cos_i - f.y;
        tdir = vec3<f32>(eta * d.x + a * hit.n.x, eta * d.y + a * hit.n.y, eta * d.z + a * hit.n.z);
    }
    return Branches(kr, kt, tdir, prune(max(w.x, max(w.y, w.z)), kr, kt, slack));
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
        let hit = surface(ray.o, ray.d, found.t, i);
        let m = materials[i];
        let keep = 1.0 - m.reflect - m.transmit;
        if (lit) {
            if (shows(s, m, keep)) {
                let l = local_light(hit.p, hit.n, -ray.d, i, hit.inside);
                counts.y = counts.y + l.shadows;
                color = color + ray.w * (keep * l.diffuse + l.specular);
            }
        } else {
            color = color + ray.w * (keep * shade_hit(s.red, s.green, s.blue, rim(i), found.d));
        }
        if (ray.depth >= lighting.sizes.z || (m.reflect <= 0.0 && m.transmit <= 0.0)) {
            continue;
        }
        let b = branches(ray.d, hit, m.reflect, m.transmit, m.ior, ray.w, ray.slack);
        let p = hit.p;
        let n = hit.n;
        let offset = OFFSET * (abs(p.x) + abs(p.y) + abs(p.z));
        if (b.pruned.transmit) {
            // it goes through the surface: from outside into the sphere, or out of it
            pending[top] = Ray(p - offset * n, b.tdir, ray.w * b.kt, b.pruned.slack, ray.depth + 1u, REFRACTION, i,
                               !hit.inside);
            top = top + 1u;
        }
        if (b.pruned.reflect) {
            let two_cos = 2.0 * hit.cos_i;
            pending[top] = Ray(p + offset * n, ray.d + two_cos * n, ray.w * b.kr, b.pruned.slack, ray.depth + 1u,
                               REFLECTION, i, hit.inside);
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
