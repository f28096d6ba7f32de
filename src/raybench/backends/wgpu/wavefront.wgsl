// kernels/wavefront.py: Whitted shading by ray, a stage an entry point over
// queues of rays (backends/wgpu/wavefront.py dispatches them); the same
// formulas in the same order as whitted.wgsl's pixel program, whose
// functions (find, shows, samples_of, toward, glint, branches) it calls, with
// sphere.wgsl's surface and rim and shade.wgsl's shade_hit and shade_miss.
//
// Every stage runs on `waves.groups` workgroups of WF_GROUP invocations,
// each taking the slots base + its index, base + the grid's invocations, ...
// of its queue, whose count it reads where it runs: the host records every
// dispatch of a frame at once. The wave a stage works on is the state word
// WAVE, which main_wf_advance moves on between waves.

struct Waves {
    ray_capacity: u32,
    shadow_capacity: u32,
    pixels: u32,
    first_pixel: u32,
    groups: u32,
    band: u32,  // the band of rows (backends/bands.py): 0, the frame's first
    _pad1: u32,
    _pad2: u32,
}

// wf_f: the two ray queues' float rows, the hits' t and half-chord, the
// shadow queue's float rows. wf_i: the ray queues' int rows, the hits'
// spheres, the shadow queue's int rows. wf_a: the state words, then each
// pixel's light as three 64-bit integers (low and high words), the pixels
// of the band from its first.
@group(0) @binding(10) var<storage, read_write> wf_f: array<f32>;
@group(0) @binding(11) var<storage, read_write> wf_i: array<i32>;
@group(0) @binding(12) var<storage, read_write> wf_a: array<atomic<u32>>;
@group(0) @binding(13) var<uniform> waves: Waves;

const WF_GROUP: u32 = 64u;
const RAY_ROWS: u32 = WF_RAY_ROWS;
const RAY_IDS: u32 = WF_RAY_IDS;
const SHADOW_ROWS: u32 = WF_SHADOW_ROWS;
const SHADOW_IDS: u32 = WF_SHADOW_IDS;
const SHADOW_BASE: u32 = WF_SHADOW_BASE;
const OVERFLOW: u32 = WF_OVERFLOW;
const WAVE: u32 = WF_WAVE;
const STATE: u32 = WF_STATE;
// A pixel's light in units of 1 / FIXED (2^28: a contribution, clamped to
// [-CLAMP, CLAMP] as kernels/wavefront.py says why, fits an i32), summed in
// 64 bits as two words, with the carry of the low word's sum.
const FIXED: f32 = 268435456.0;
const CLAMP: f32 = WF_CLAMP;
const R_PIXEL: u32 = 0u;
const R_DEPTH: u32 = 1u;
const R_KIND: u32 = 2u;
const R_OWN: u32 = 3u;
const R_INSIDE: u32 = 4u;

fn ray_f(queue: u32, row: u32, i: u32) -> f32 {
    return wf_f[(queue * RAY_ROWS + row) * waves.ray_capacity + i];
}

fn set_ray_f(queue: u32, row: u32, i: u32, value: f32) {
    wf_f[(queue * RAY_ROWS + row) * waves.ray_capacity + i] = value;
}

fn ray_i(queue: u32, row: u32, i: u32) -> i32 {
    return wf_i[(queue * RAY_IDS + row) * waves.ray_capacity + i];
}

fn set_ray_i(queue: u32, row: u32, i: u32, value: i32) {
    wf_i[(queue * RAY_IDS + row) * waves.ray_capacity + i] = value;
}

fn hit_f(row: u32, i: u32) -> u32 {  // the index of a hit's t (row 0) or half-chord (row 1)
    return (2u * RAY_ROWS + row) * waves.ray_capacity + i;
}

fn hit_i(i: u32) -> u32 {
    return 2u * RAY_IDS * waves.ray_capacity + i;
}

fn shadow_f(row: u32, i: u32) -> u32 {
    return (2u * RAY_ROWS + 2u) * waves.ray_capacity + row * waves.shadow_capacity + i;
}

fn shadow_i(row: u32, i: u32) -> u32 {
    return (2u * RAY_IDS + 1u) * waves.ray_capacity + row * waves.shadow_capacity + i;
}

struct WaveRay {
    o: vec3<f32>,
    d: vec3<f32>,
    w: vec3<f32>,
    slack: f32,
    pixel: i32,
    depth: u32,
    kind: i32,
    own: i32,
    inside: bool,
}

fn load_ray(queue: u32, i: u32) -> WaveRay {
    return WaveRay(
        vec3<f32>(ray_f(queue, 0u, i), ray_f(queue, 1u, i), ray_f(queue, 2u, i)),
        vec3<f32>(ray_f(queue, 3u, i), ray_f(queue, 4u, i), ray_f(queue, 5u, i)),
        vec3<f32>(ray_f(queue, 6u, i), ray_f(queue, 7u, i), ray_f(queue, 8u, i)),
        ray_f(queue, 9u, i),
        ray_i(queue, R_PIXEL, i), u32(ray_i(queue, R_DEPTH, i)), ray_i(queue, R_KIND, i), ray_i(queue, R_OWN, i),
        ray_i(queue, R_INSIDE, i) != 0);
}

fn put_ray(queue: u32, i: u32, o: vec3<f32>, d: vec3<f32>, w: vec3<f32>, slack: f32, pixel: i32, depth: u32,
           kind: i32, own: i32, inside: bool) {
    set_ray_f(queue, 0u, i, o.x);
    set_ray_f(queue, 1u, i, o.y);
    set_ray_f(queue, 2u, i, o.z);
    set_ray_f(queue, 3u, i, d.x);
    set_ray_f(queue, 4u, i, d.y);
    set_ray_f(queue, 5u, i, d.z);
    set_ray_f(queue, 6u, i, w.x);
    set_ray_f(queue, 7u, i, w.y);
    set_ray_f(queue, 8u, i, w.z);
    set_ray_f(queue, 9u, i, slack);
    set_ray_i(queue, R_PIXEL, i, pixel);
    set_ray_i(queue, R_DEPTH, i, i32(depth));
    set_ray_i(queue, R_KIND, i, kind);
    set_ray_i(queue, R_OWN, i, own);
    set_ray_i(queue, R_INSIDE, i, select(0, 1, inside));
}

// wavefront.fixed, and its sum in two words.
fn add_channel(word: u32, c: f32) {
    if (c == 0.0) {
        return;
    }
    let v = i32(clamp(c, -CLAMP, CLAMP) * FIXED);
    let low = bitcast<u32>(v);
    let old = atomicAdd(&wf_a[word], low);
    var high = select(0u, 0xffffffffu, v < 0);
    if (old + low < old) {
        high = high + 1u;
    }
    if (high != 0u) {
        atomicAdd(&wf_a[word + 1u], high);
    }
}

fn add_light(pixel: i32, c: vec3<f32>) {
    let word = STATE + 6u * (u32(pixel) - waves.first_pixel);
    add_channel(word, c.x);
    add_channel(word + 2u, c.y);
    add_channel(word + 4u, c.z);
}

// wavefront.resolve: a channel's sum as a float, the words zeroed for the next frame.
fn take_channel(word: u32) -> f32 {
    let low = atomicExchange(&wf_a[word], 0u);
    let high = bitcast<i32>(atomicExchange(&wf_a[word + 1u], 0u));
    return f32(high) * (4294967296.0 / FIXED) + f32(low) / FIXED;
}

// whitted.background
fn background_of(pixel: i32) -> vec3<f32> {
    if (lighting.background.w > 0.0) {
        return shade_miss(f32(u32(pixel) % frame.width), f32(u32(pixel) / frame.width));
    }
    return lighting.background.xyz;
}

var<workgroup> wg_count: atomic<u32>;
var<workgroup> wg_base: u32;
var<workgroup> wg_n: u32;
var<workgroup> wg_wave: u32;
var<workgroup> wf_tally: array<atomic<u32>, 4>;

// The first of n slots for this invocation in the queue whose count is
// state word `which`; every invocation of the workgroup calls it. Flags
// OVERFLOW where the workgroup's slots run past capacity.
fn claim(n: u32, which: u32, capacity: u32, me: u32) -> u32 {
    var mine = 0u;
    if (n > 0u) {
        mine = atomicAdd(&wg_count, n);
    }
    workgroupBarrier();
    if (me == 0u) {
        let total = atomicLoad(&wg_count);
        atomicStore(&wg_count, 0u);
        var start = 0u;
        if (total > 0u) {
            start = atomicAdd(&wf_a[which], total);
            if (start + total > capacity) {
                atomicStore(&wf_a[OVERFLOW], 1u);
            }
        }
        wg_base = start;
    }
    return workgroupUniformLoad(&wg_base) + mine;
}

// The wave this dispatch works on, and the count of the queue `which`
// (plus the wave) holds, capped at capacity: the same in every invocation.
fn wave_and_count(which: u32, capacity: u32, me: u32) -> vec2<u32> {
    if (me == 0u) {
        let wave = atomicLoad(&wf_a[WAVE]);
        wg_wave = wave;
        wg_n = min(atomicLoad(&wf_a[which + wave]), capacity);
    }
    return vec2<u32>(workgroupUniformLoad(&wg_wave), workgroupUniformLoad(&wg_n));
}

@compute @workgroup_size(WF_GROUP)
fn main_wf_start(@builtin(local_invocation_index) me: u32) {
    for (var i = me; i < STATE; i = i + WF_GROUP) {
        atomicStore(&wf_a[i], 0u);
    }
    if (me < 4u && waves.band == 0u) {  // the frame's ray tally, summed over its bands
        atomicStore(&rays[me], 0u);
    }
}

@compute @workgroup_size(WF_GROUP)
fn main_wf_primary(@builtin(global_invocation_id) id: vec3<u32>) {
    if (id.x == 0u) {
        atomicStore(&wf_a[0], waves.pixels);
    }
    let origin = frame.origin.xyz;
    for (var i = id.x; i < waves.pixels; i = i + waves.groups * WF_GROUP) {
        let pixel = waves.first_pixel + i;
        let d = primary_ray(pixel % frame.width, pixel / frame.width);
        put_ray(0u, i, origin, d, vec3<f32>(1.0, 1.0, 1.0), CUTOFF, i32(pixel), 0u, PRIMARY, -1, false);
    }
}

@compute @workgroup_size(WF_GROUP)
fn main_wf_extend(@builtin(workgroup_id) group: vec3<u32>, @builtin(local_invocation_index) me: u32) {
    if (me < 4u) {
        atomicStore(&wf_tally[me], 0u);
    }
    let wn = wave_and_count(0u, waves.ray_capacity, me);
    let queue = wn.x % 2u;
    let n = wn.y;
    for (var base = group.x * WF_GROUP; base < n; base = base + waves.groups * WF_GROUP) {
        let i = base + me;
        if (i < n) {
            let ray = load_ray(queue, i);
            let found = find(ray.o, ray.d, FAR, false, ray.own, ray.inside);
            wf_f[hit_f(0u, i)] = found.t;
            wf_f[hit_f(1u, i)] = found.d;
            wf_i[hit_i(i)] = found.index;
            if (ray.kind == PRIMARY) {
                hits[ray.pixel] = found.index;
            }
            atomicAdd(&wf_tally[u32(ray.kind)], 1u);
        }
    }
    workgroupBarrier();
    if (me < 4u && me != 1u) {
        let k = atomicLoad(&wf_tally[me]);
        if (k > 0u) {
            atomicAdd(&rays[me], k);
        }
    }
}

@compute @workgroup_size(WF_GROUP)
fn main_wf_shade(@builtin(workgroup_id) group: vec3<u32>, @builtin(local_invocation_index) me: u32) {
    if (me == 0u) {
        atomicStore(&wg_count, 0u);
    }
    let wn = wave_and_count(0u, waves.ray_capacity, me);
    let wave = wn.x;
    let queue = wave % 2u;
    let next = 1u - queue;
    let n = wn.y;
    for (var base = group.x * WF_GROUP; base < n; base = base + waves.groups * WF_GROUP) {
        let i = base + me;
        var h = -1;
        var n_shadows = 0u;
        var ray: WaveRay;
        var hit = Surface(vec3<f32>(0.0), vec3<f32>(0.0), 0.0, false);
        var keep = 0.0;
        var b = Branches(0.0, 0.0, vec3<f32>(0.0), Pruned(false, false, 0.0));
        if (i < n) {
            ray = load_ray(queue, i);
            h = wf_i[hit_i(i)];
            if (h < 0) {
                add_light(ray.pixel, ray.w * background_of(ray.pixel));
            } else {
                let s = spheres[h];
                hit = surface(ray.o, ray.d, wf_f[hit_f(0u, i)], h);
                let m = materials[h];
                keep = 1.0 - m.reflect - m.transmit;
                if (lighting.sizes.x > 0u) {
                    if (shows(s, m, keep)) {
                        add_light(ray.pixel, ray.w * (keep * (lighting.ambient.xyz * vec3<f32>(s.red, s.green, s.blue))));
                        for (var light = 0u; light < lighting.sizes.x; light = light + 1u) {
                            let samples = samples_of(light);
                            let share = 1.0 / f32(samples);
                            for (var k = 0u; k < samples; k = k + 1u) {
                                if (toward(lifted(hit.p, hit.n), hit.n, light, k, share).facing > 0.0) {
                                    n_shadows = n_shadows + 1u;
                                }
                            }
                        }
                    }
                } else {
                    let shaded = shade_hit(s.red, s.green, s.blue, rim(h), wf_f[hit_f(1u, i)]);
                    add_light(ray.pixel, ray.w * (keep * shaded));
                }
                if (ray.depth < lighting.sizes.z && (m.reflect > 0.0 || m.transmit > 0.0)) {
                    b = branches(ray.d, hit, m.reflect, m.transmit, m.ior, ray.w, ray.slack);
                }
            }
        }
        let n_children = select(0u, 1u, b.pruned.reflect) + select(0u, 1u, b.pruned.transmit);
        let first_shadow = claim(n_shadows, SHADOW_BASE + wave, waves.shadow_capacity, me);
        let first_child = claim(n_children, wave + 1u, waves.ray_capacity, me);
        if (n_shadows > 0u) {
            // wavefront.put_shadows
            let s = spheres[h];
            let m = materials[h];
            let kd = keep * vec3<f32>(s.red, s.green, s.blue);
            let p = lifted(hit.p, hit.n);
            let nrm = hit.n;
            let v = -ray.d;
            var k = first_shadow;
            for (var light = 0u; light < lighting.sizes.x; light = light + 1u) {
                let samples = samples_of(light);
                let share = 1.0 / f32(samples);
                for (var j = 0u; j < samples; j = j + 1u) {
                    let to = toward(p, nrm, light, j, share);
                    if (to.facing <= 0.0) {
                        continue;
                    }
                    if (k < waves.shadow_capacity) {
                        let g = glint(m.specular, m.shininess, to.facing, nrm, v, to.l);
                        wf_f[shadow_f(0u, k)] = p.x;
                        wf_f[shadow_f(1u, k)] = p.y;
                        wf_f[shadow_f(2u, k)] = p.z;
                        wf_f[shadow_f(3u, k)] = to.l.x;
                        wf_f[shadow_f(4u, k)] = to.l.y;
                        wf_f[shadow_f(5u, k)] = to.l.z;
                        wf_f[shadow_f(6u, k)] = to.dist;
                        wf_f[shadow_f(7u, k)] = ray.w.x * (to.c.x * kd.x * to.facing + to.c.x * g);
                        wf_f[shadow_f(8u, k)] = ray.w.y * (to.c.y * kd.y * to.facing + to.c.y * g);
                        wf_f[shadow_f(9u, k)] = ray.w.z * (to.c.z * kd.z * to.facing + to.c.z * g);
                        wf_i[shadow_i(0u, k)] = ray.pixel;
                        wf_i[shadow_i(1u, k)] = h;
                        wf_i[shadow_i(2u, k)] = select(0, 1, hit.inside);
                    }
                    k = k + 1u;
                }
            }
        }
        if (n_children > 0u) {
            // wavefront.put_children: the refraction first, then the reflection
            let p = hit.p;
            let nrm = hit.n;
            let offset = OFFSET * (abs(p.x) + abs(p.y) + abs(p.z));
            var k = first_child;
            if (b.pruned.transmit) {
                if (k < waves.ray_capacity) {
                    put_ray(next, k, p - offset * nrm, b.tdir, ray.w * b.kt, b.pruned.slack, ray.pixel, ray.depth + 1u,
                            REFRACTION, h, !hit.inside);
                }
                k = k + 1u;
            }
            if (b.pruned.reflect && k < waves.ray_capacity) {
                let two_cos = 2.0 * hit.cos_i;
                put_ray(next, k, p + offset * nrm, ray.d + two_cos * nrm, ray.w * b.kr, b.pruned.slack, ray.pixel,
                        ray.depth + 1u, REFLECTION, h, hit.inside);
            }
        }
    }
}

@compute @workgroup_size(WF_GROUP)
fn main_wf_shadow(@builtin(workgroup_id) group: vec3<u32>, @builtin(local_invocation_index) me: u32) {
    let wn = wave_and_count(SHADOW_BASE, waves.shadow_capacity, me);
    let n = wn.y;
    if (group.x == 0u && me == 0u && n > 0u) {
        atomicAdd(&rays[1], n);
    }
    for (var base = group.x * WF_GROUP; base < n; base = base + waves.groups * WF_GROUP) {
        let i = base + me;
        if (i < n) {
            let o = vec3<f32>(wf_f[shadow_f(0u, i)], wf_f[shadow_f(1u, i)], wf_f[shadow_f(2u, i)]);
            let d = vec3<f32>(wf_f[shadow_f(3u, i)], wf_f[shadow_f(4u, i)], wf_f[shadow_f(5u, i)]);
            let found = find(o, d, wf_f[shadow_f(6u, i)], true, wf_i[shadow_i(1u, i)], wf_i[shadow_i(2u, i)] != 0);
            if (found.index < 0) {
                add_light(wf_i[shadow_i(0u, i)],
                          vec3<f32>(wf_f[shadow_f(7u, i)], wf_f[shadow_f(8u, i)], wf_f[shadow_f(9u, i)]));
            }
        }
    }
}

@compute @workgroup_size(1)
fn main_wf_advance() {
    atomicAdd(&wf_a[WAVE], 1u);
}

@compute @workgroup_size(WF_GROUP)
fn main_wf_finish(@builtin(global_invocation_id) id: vec3<u32>) {
    for (var i = id.x; i < waves.pixels; i = i + waves.groups * WF_GROUP) {
        let pixel = waves.first_pixel + i;
        let word = STATE + 6u * i;
        let c = vec3<f32>(take_channel(word), take_channel(word + 2u), take_channel(word + 4u));
        let bytes = vec3<f32>(to_byte(c.x), to_byte(c.y), to_byte(c.z));
        textureStore(image, vec2<i32>(i32(pixel % frame.width), i32(pixel / frame.width)), vec4<f32>(bytes / 255.0, 1.0));
    }
}
