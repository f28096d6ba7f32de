// kernels/primitives/sphere.py's WGSL twin: everything the walks and the
// shading know about a sphere. Nothing outside this piece reads a sphere's
// centre or radius; each function bears its Python twin's name and does its
// arithmetic in the same order, term by term (tests/test_wgsl_parity.py
// holds each pair to the same bits). WGSL takes no storage buffer as an
// argument, so where the Python takes the buffer (read(buffer, k)), the
// twin reads the binding itself: `spheres` (common.wgsl) or `ordered`.

// One sphere: the (7, N) float32 columns of Scene.spheres, padded to 32 bytes.
// Scalars, not vec3s, so the arithmetic below is the kernels' own, term by term.
struct Sphere {
    cx: f32, cy: f32, cz: f32, r: f32,
    red: f32, green: f32, blue: f32, _pad: f32,
}

// bvh.ordered, one row per sphere (cx, cy, cz, r) in leaf order: the very
// float32 values of the scene, so the exact test is the brute-force one. The
// tree's binding, declared here because its rows are the sphere's
// (LEAF_ROWS); a shader without the tree (brute.wgsl) never reads it, so its
// automatic layout leaves it out.
@group(0) @binding(5) var<storage, read> ordered: array<vec4<f32>>;

// read_sphere: the Python's read, sphere k of the scene's buffer, (cx, cy,
// cz, r). Not named read: that is WGSL's access mode, which every storage
// binding names (var<storage, read>), and a function of that name shadows it.
// The row is loaded whole, as the shading's own `spheres[i]` is: the same
// wide loads, which the driver then shares between the two.
fn read_sphere(k: i32) -> vec4<f32> {
    let s = spheres[k];
    return vec4<f32>(s.cx, s.cy, s.cz, s.r);
}

// read_leaf: sphere k of the tree's leaf buffer, (cx, cy, cz, r).
fn read_leaf(k: i32) -> vec4<f32> {
    return ordered[k];
}

// along: v = EO.dir, how far along the ray the sphere's centre lies.
fn along(ex: f32, ey: f32, ez: f32, dx: f32, dy: f32, dz: f32) -> f32 {
    return ex * dx + ey * dy + ez * dz;
}

// chord: (v, disc), v = EO.dir and disc = r^2 - |EO - v dir|^2, rather than
// the thesis's r^2 - (EO.EO - v^2), which loses every digit for small, far
// spheres in float32 (the Python docstring says why).
fn chord(ex: f32, ey: f32, ez: f32, r: f32, dx: f32, dy: f32, dz: f32) -> vec2<f32> {
    let v = along(ex, ey, ez, dx, dy, dz);
    let px = ex - v * dx;
    let py = ey - v * dy;
    let pz = ez - v * dz;
    return vec2<f32>(v, r * r - (px * px + py * py + pz * pz));
}

// intersect_relative: (e, r), the sphere's centre minus the ray's origin,
// and its radius; d: the unit ray. Returns (t, d), t = -1 on a miss.
fn intersect_relative(ex: f32, ey: f32, ez: f32, r: f32, dx: f32, dy: f32, dz: f32) -> vec2<f32> {
    let vd = chord(ex, ey, ez, r, dx, dy, dz);
    if (vd.y < 0.0) {
        return vec2<f32>(-1.0, 0.0);
    }
    let d = sqrt(vd.y);
    return vec2<f32>(vd.x - d, d);
}

// intersect_ahead: the secondary rays' test, the first crossing ahead: the
// near root from outside, the far root from inside or where far_only.
fn intersect_ahead(ex: f32, ey: f32, ez: f32, r: f32, dx: f32, dy: f32, dz: f32, far_only: bool) -> vec2<f32> {
    let vd = chord(ex, ey, ez, r, dx, dy, dz);
    if (vd.y < 0.0) {
        return vec2<f32>(-1.0, 0.0);
    }
    let d = sqrt(vd.y);
    var t = vd.x - d;
    if (far_only || t <= 0.0) {
        t = vd.x + d;
    }
    return vec2<f32>(t, d);
}

// intersect: intersect_relative for a ray from o; c: read_sphere's (cx, cy, cz, r).
fn intersect(o: vec3<f32>, dir: vec3<f32>, c: vec4<f32>) -> vec2<f32> {
    return intersect_relative(c.x - o.x, c.y - o.y, c.z - o.z, c.w, dir.x, dir.y, dir.z);
}

// hit and hit_ahead on the scene's spheres, leaf_hit and leaf_hit_ahead on
// the tree's leaves: the Python makes each pair from one source, given the
// reader (make's `tests`); a WGSL function takes no function, so two pairs.

// hit: the thesis's primary test of sphere k: (t, d).
fn hit(k: i32, o: vec3<f32>, dir: vec3<f32>) -> vec2<f32> {
    return intersect(o, dir, read_sphere(k));
}

// hit_ahead: the secondary rays' test of sphere k; is_own: k is the sphere
// the ray leaves, going into it (meets_own), met at its far root.
fn hit_ahead(k: i32, o: vec3<f32>, dir: vec3<f32>, is_own: bool) -> vec2<f32> {
    let c = read_sphere(k);
    return intersect_ahead(c.x - o.x, c.y - o.y, c.z - o.z, c.w, dir.x, dir.y, dir.z, is_own);
}

// leaf_hit: hit on the tree's leaf k.
fn leaf_hit(k: i32, o: vec3<f32>, dir: vec3<f32>) -> vec2<f32> {
    return intersect(o, dir, read_leaf(k));
}

// leaf_hit_ahead: hit_ahead on the tree's leaf k.
fn leaf_hit_ahead(k: i32, o: vec3<f32>, dir: vec3<f32>, is_own: bool) -> vec2<f32> {
    let c = read_leaf(k);
    return intersect_ahead(c.x - o.x, c.y - o.y, c.z - o.z, c.w, dir.x, dir.y, dir.z, is_own);
}

// from_origin: sphere k of the tree's leaf buffer as rays from o see it,
// (EO, r): hit_from's and hit_ahead_from's first argument.
fn from_origin(k: i32, o: vec3<f32>) -> vec4<f32> {
    let c = read_leaf(k);
    return vec4<f32>(c.x - o.x, c.y - o.y, c.z - o.z, c.w);
}

// hit_from: leaf_hit for a ray whose origin `seen` is from.
fn hit_from(seen: vec4<f32>, dir: vec3<f32>) -> vec2<f32> {
    return intersect_relative(seen.x, seen.y, seen.z, seen.w, dir.x, dir.y, dir.z);
}

// hit_ahead_from: leaf_hit_ahead for a ray whose origin `seen` is from.
fn hit_ahead_from(seen: vec4<f32>, dir: vec3<f32>, is_own: bool) -> vec2<f32> {
    return intersect_ahead(seen.x, seen.y, seen.z, seen.w, dir.x, dir.y, dir.z, is_own);
}

// meets_own: whether a ray that leaves a sphere can meet it again: only
// going into it, at the far root (the Python docstring says why).
fn meets_own(own_inside: bool) -> bool {
    return own_inside;
}

// surface's results: the hit point, the unit normal and cos_i on the side
// the ray comes from, and whether it meets the sphere from within.
struct Surface {
    p: vec3<f32>,
    n: vec3<f32>,
    cos_i: f32,
    inside: bool,
}

// surface: the hit of a ray on sphere i at t.
fn surface(o: vec3<f32>, d: vec3<f32>, t: f32, i: i32) -> Surface {
    let px = o.x + t * d.x;
    let py = o.y + t * d.y;
    let pz = o.z + t * d.z;
    let c = read_sphere(i);
    let inv_r = 1.0 / c.w;
    var nx = (px - c.x) * inv_r;
    var ny = (py - c.y) * inv_r;
    var nz = (pz - c.z) * inv_r;
    let inv_n = 1.0 / sqrt(nx * nx + ny * ny + nz * nz);
    nx = nx * inv_n;
    ny = ny * inv_n;
    nz = nz * inv_n;
    var cos_i = -(nx * d.x + ny * d.y + nz * d.z);
    let inside = cos_i < 0.0;  // the ray meets the sphere from within
    if (inside) {
        nx = -nx;
        ny = -ny;
        nz = -nz;
        cos_i = -cos_i;
    }
    return Surface(vec3<f32>(px, py, pz), vec3<f32>(nx, ny, nz), cos_i, inside);
}

// rim: what the thesis's shading divides a hit's half-chord by (shade_hit).
fn rim(i: i32) -> f32 {
    return read_sphere(i).w;
}
