// kernels/primitives/triangle.py's WGSL twin: the watertight ray/triangle
// test (Woop, Benthin and Wald 2013) and the answers the walks and the
// shading read. Each function bears its Python twin's name. shader.py puts it
// (after triangle_box.wgsl: pad and box) in sphere.wgsl's place for a
// triangle's shader; tests/test_triangle_wgsl.py runs it on its own.
//
// WGSL has no float64, where the Python works out the edge functions, det,
// T and the normal. So:
// - edge: a*b - c*d with the exact sign, in float32: the two rounded
//   products decide where they differ (rounding is monotone, so their order
//   is the exact products'); where they are equal, the products' exact
//   rounding errors (Dekker's split) decide. The same signs and zeros as the
//   Python's float64, and a shared edge seen the other way round gets
//   exactly the negation: watertight, on an adapter that fuses no product
//   into the subtraction (lavapipe; a GPU compiler that fuses a * b - q
//   computes the sign of a*b - round(c*d), no longer exact).
// - det, T and t in float32: hit or miss as the Python, t and the cosine
//   within a few ulps of it. T is a cube of coordinates: under about 1e12
//   (the Python's reach is the scene's 1e15).
// - zero area as the float32 edges B - A and C - A see it (their cross
//   product's components by edge): the Python's wherever those differences
//   are exact in float32 (a repeated vertex; vertices within a factor 2 of
//   each other on each axis).

// The leaf buffer: triangle k's nine values (A, B, C; x, y, z each) at
// 9k ... 9k + 8 (bvh.ordered transposed).
@group(0) @binding(5) var<storage, read> ordered: array<f32>;

// A triangle of the scene's buffer (meshes.mesh_leaves' column, as
// compute.py's triangle rows lay it out): its vertices, its colour, and its
// corners' normals, zeros where the mesh has none. common.wgsl binds the
// scene's buffer as `spheres: array<Sphere>`, and the shading (trace.wgsl,
// whitted.wgsl, wavefront.wgsl) reads a hit's colour as spheres[i].red,
// green and blue: the triangle's row answers to those names, so that those
// pieces, and with them every sphere shader, stay as they are.
struct Facet {
    v: array<f32, 9>,
    red: f32,
    green: f32,
    blue: f32,
    n: array<f32, 9>,
}
alias Sphere = Facet;

const TRI_MISS: vec2<f32> = vec2<f32>(-1.0, 0.0);
// Dekker's splitter for float32's 24-bit significand: 2^12 + 1.
const TRI_SPLIT: f32 = 4097.0;

struct Triangle {
    a: vec3<f32>,
    b: vec3<f32>,
    c: vec3<f32>,
}

// Woop's answer: U, V, W (the weights of A, B, C), T, all times det.
struct Woop {
    u: f32,
    v: f32,
    w: f32,
    t: f32,
    det: f32,
}

// seen_from's: the vertices relative to a packet's origin, and the plane's normal.
struct Seen {
    a: vec3<f32>,
    b: vec3<f32>,
    c: vec3<f32>,
    n: vec3<f32>,
}

// read_triangle: the Python's read on the scene's buffer (not named read:
// WGSL's access mode). Each reader names one binding, so that a shader that
// reads only the leaves does not bind the scene's buffer.
fn read_triangle(k: i32) -> Triangle {
    return corners(spheres[k].v);
}

// read_leaf: triangle k of the tree's leaf buffer.
fn read_leaf(k: i32) -> Triangle {
    let i = 9 * k;
    return corners(array<f32, 9>(ordered[i], ordered[i + 1], ordered[i + 2], ordered[i + 3], ordered[i + 4],
        ordered[i + 5], ordered[i + 6], ordered[i + 7], ordered[i + 8]));
}

// corners: a buffer's nine values of a triangle (A, B, C) as its three corners.
fn corners(v: array<f32, 9>) -> Triangle {
    return Triangle(vec3<f32>(v[0], v[1], v[2]), vec3<f32>(v[3], v[4], v[5]), vec3<f32>(v[6], v[7], v[8]));
}

// permute: axis kz last, the other two in cyclic order.
fn permute(v: vec3<f32>, kz: i32) -> vec3<f32> {
    if (kz == 0) {
        return vec3<f32>(v.y, v.z, v.x);
    }
    if (kz == 1) {
        return vec3<f32>(v.z, v.x, v.y);
    }
    return v;
}

// product_error: a * b - p exactly, for p = a * b rounded (Dekker's two-product).
fn product_error(a: f32, b: f32, p: f32) -> f32 {
    let ca = TRI_SPLIT * a;
    let ah = ca - (ca - a);
    let al = a - ah;
    let cb = TRI_SPLIT * b;
    let bh = cb - (cb - b);
    let bl = b - bh;
    return ((ah * bh - p) + ah * bl + al * bh) + al * bl;
}

// edge: a * b - c * d, its sign and its zero exact (the header says why).
fn edge(a: f32, b: f32, c: f32, d: f32) -> f32 {
    let p = a * b;
    let q = c * d;
    if (p != q) {
        return p - q;
    }
    return product_error(a, b, p) - product_error(c, d, q);
}

// woop: the watertight test of the ray from the origin along d against the
// triangle a, b, c relative to that origin; det 0 where it misses.
fn woop(a: vec3<f32>, b: vec3<f32>, c: vec3<f32>, d: vec3<f32>) -> Woop {
    let ad = abs(d);
    var kz = 2;
    if (ad.x > ad.y && ad.x > ad.z) {
        kz = 0;
    } else if (ad.y > ad.z) {
        kz = 1;
    }
    let p = permute(d, kz);
    let sx = p.x / p.z;
    let sy = p.y / p.z;
    let sz = 1.0 / p.z;
    let pa = permute(a, kz);
    let pb = permute(b, kz);
    let pc = permute(c, kz);
    let a_x = pa.x - sx * pa.z;
    let a_y = pa.y - sy * pa.z;
    let b_x = pb.x - sx * pb.z;
    let b_y = pb.y - sy * pb.z;
    let c_x = pc.x - sx * pc.z;
    let c_y = pc.y - sy * pc.z;
    let u = edge(c_x, b_y, c_y, b_x);
    let v = edge(a_x, c_y, a_y, c_x);
    let w = edge(b_x, a_y, b_y, a_x);
    if ((u < 0.0 || v < 0.0 || w < 0.0) && (u > 0.0 || v > 0.0 || w > 0.0)) {
        return Woop(0.0, 0.0, 0.0, 0.0, 0.0);
    }
    let det = u + v + w;
    let t = u * (sz * pa.z) + v * (sz * pb.z) + w * (sz * pc.z);
    return Woop(u, v, w, t, det);
}

// normal: the plane's unit normal, (0, 0, 0) for zero area (as the float32 edges see it).
fn normal(a: vec3<f32>, b: vec3<f32>, c: vec3<f32>) -> vec3<f32> {
    let e1 = b - a;
    let e2 = c - a;
    let n = vec3<f32>(edge(e1.y, e2.z, e1.z, e2.y), edge(e1.z, e2.x, e1.x, e2.z), edge(e1.x, e2.y, e1.y, e2.x));
    if (n.x == 0.0 && n.y == 0.0 && n.z == 0.0) {
        return n;
    }
    // scaled by its largest component first, so that its square cannot overflow
    let m = max(abs(n.x), max(abs(n.y), abs(n.z)));
    let s = n / m;
    return s / sqrt(s.x * s.x + s.y * s.y + s.z * s.z);
}

// finish: (t, cos = |n.d|), or the miss.
fn finish(t: f32, det: f32, n: vec3<f32>, d: vec3<f32>) -> vec2<f32> {
    if (det == 0.0 || (n.x == 0.0 && n.y == 0.0 && n.z == 0.0)) {
        return TRI_MISS;
    }
    return vec2<f32>(t / det, abs(n.x * d.x + n.y * d.y + n.z * d.z));
}

// intersect: the ray from o along the unit d against the triangle.
fn intersect(o: vec3<f32>, d: vec3<f32>, tri: Triangle) -> vec2<f32> {
    let r = woop(tri.a - o, tri.b - o, tri.c - o, d);
    if (r.det == 0.0) {
        return TRI_MISS;
    }
    return finish(r.t, r.det, normal(tri.a, tri.b, tri.c), d);
}

fn hit(k: i32, o: vec3<f32>, d: vec3<f32>) -> vec2<f32> {
    return intersect(o, d, read_triangle(k));
}

// A ray never meets the plane it leaves again: its own triangle is a miss
// (select: the test's answer is dropped, not skipped, in a function this short).
fn hit_ahead(k: i32, o: vec3<f32>, d: vec3<f32>, is_own: bool) -> vec2<f32> {
    return select(hit(k, o, d), TRI_MISS, is_own);
}

fn leaf_hit(k: i32, o: vec3<f32>, d: vec3<f32>) -> vec2<f32> {
    return intersect(o, d, read_leaf(k));
}

fn leaf_hit_ahead(k: i32, o: vec3<f32>, d: vec3<f32>, is_own: bool) -> vec2<f32> {
    return select(leaf_hit(k, o, d), TRI_MISS, is_own);
}

fn seen_from(row: Triangle, o: vec3<f32>) -> Seen {
    return Seen(row.a - o, row.b - o, row.c - o, normal(row.a, row.b, row.c));
}

fn from_origin(k: i32, o: vec3<f32>) -> Seen {
    return seen_from(read_leaf(k), o);
}

fn hit_from(seen: Seen, d: vec3<f32>) -> vec2<f32> {
    let r = woop(seen.a, seen.b, seen.c, d);
    return finish(r.t, r.det, seen.n, d);
}

fn hit_ahead_from(seen: Seen, d: vec3<f32>, is_own: bool) -> vec2<f32> {
    if (is_own) {
        return TRI_MISS;
    }
    return hit_from(seen, d);
}

fn meets_own(own_inside: bool) -> bool {
    return false;
}

// box_of: a leaf row's padded box, lo then hi (triangle_box.wgsl's padded).
fn box_of(row: Triangle) -> array<vec3<f32>, 2> {
    let e = padded(row.a, row.b, row.c);
    return array<vec3<f32>, 2>(e.centre - e.half_size, e.centre + e.half_size);
}

fn bounds(k: i32) -> array<vec3<f32>, 2> {
    return box_of(read_leaf(k));
}

// rim: what the thesis's shading divides the datum (the cosine) by.
fn rim(k: i32) -> f32 {
    return 1.0;
}

// surface's results, as whitted.wgsl and wavefront.wgsl read them: the
// struct sphere.wgsl declares for the sphere (the point, the unit normal and
// cos_i on the ray's side, whether the ray meets the back face), declared
// here too as a triangle's shader has no sphere.wgsl.
struct Surface { p: vec3<f32>, n: vec3<f32>, cos_i: f32, inside: bool }

// surface: the hit of a ray on triangle i at t: the plane's normal turned to
// the ray's side, or where the row has its corners' normals their blend by
// the hit's barycentrics (woop run again on the same ray), turned as the
// plane's is, unless that leaves it facing away from the ray. A row of zero
// normals (a mesh without them) gives the plane's, as the Python's buffer
// without those rows does: the blend is then 0, which the Python also
// answers with the plane's normal.
fn surface(o: vec3<f32>, d: vec3<f32>, t: f32, i: i32) -> Surface {
    let p = vec3<f32>(o.x + t * d.x, o.y + t * d.y, o.z + t * d.z);
    let tri = read_triangle(i);
    var g = normal(tri.a, tri.b, tri.c);
    var cos_g = -(g.x * d.x + g.y * d.y + g.z * d.z);
    let inside = cos_g < 0.0;  // the ray meets the back face
    if (inside) {
        g = -g;
        cos_g = -cos_g;
    }
    let flat = Surface(p, g, cos_g, inside);
    let c = spheres[i].n;
    let na = vec3<f32>(c[0], c[1], c[2]);
    let nb = vec3<f32>(c[3], c[4], c[5]);
    let nc = vec3<f32>(c[6], c[7], c[8]);
    if (all(na == vec3<f32>(0.0)) && all(nb == vec3<f32>(0.0)) && all(nc == vec3<f32>(0.0))) {
        return flat;  // no corners' normals: not worth the test again
    }
    let r = woop(tri.a - o, tri.b - o, tri.c - o, d);
    if (r.det == 0.0) {
        return flat;
    }
    let wa = r.u / r.det;
    let wb = r.v / r.det;
    let wc = r.w / r.det;
    var nx = wa * na.x + wb * nb.x + wc * nc.x;
    var ny = wa * na.y + wb * nb.y + wc * nc.y;
    var nz = wa * na.z + wb * nb.z + wc * nc.z;
    let nn = nx * nx + ny * ny + nz * nz;
    if (!(nn > 0.0)) {
        return flat;
    }
    let inv_n = 1.0 / sqrt(nn);
    nx = nx * inv_n;
    ny = ny * inv_n;
    nz = nz * inv_n;
    if (nx * g.x + ny * g.y + nz * g.z < 0.0) {
        nx = -nx;
        ny = -ny;
        nz = -nz;
    }
    let cos_i = -(nx * d.x + ny * d.y + nz * d.z);
    if (cos_i <= 0.0) {
        return flat;
    }
    return Surface(p, vec3<f32>(nx, ny, nz), cos_i, inside);
}
