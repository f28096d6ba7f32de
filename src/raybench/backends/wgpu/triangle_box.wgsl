// kernels/primitives/triangle.py's pad and box: a triangle's box as the
// walks (triangle.wgsl's box_of) and the builders (triangle_build.wgsl's
// extent) both see it, in one piece that the host puts before either, so the
// two cannot drift apart. The Python's arithmetic, term by term.

const TRI_PAD: f32 = BVH_PAD;

// An extent: a box as its centre and half its size on each axis.
struct Extent {
    centre: vec3<f32>,
    half_size: vec3<f32>,
}

// pad: (|centre|_1 + hx + hy + hz) * PAD, as the Python's.
fn pad(m: vec3<f32>, h: vec3<f32>) -> f32 {
    return ((abs(m.x) + abs(m.y) + abs(m.z)) + (h.x + h.y + h.z)) * TRI_PAD;
}

// box: the unpadded box of vertices a, b, c: centre (min + max) * 0.5 per
// axis, half the larger of its distances to min and max.
fn box(a: vec3<f32>, b: vec3<f32>, c: vec3<f32>) -> Extent {
    let lo = min(min(a, b), c);
    let hi = max(max(a, b), c);
    let m = (lo + hi) * 0.5;
    return Extent(m, max(m - lo, hi - m));
}

// padded: box grown by pad on every side (the Python's extent, from the vertices).
fn padded(a: vec3<f32>, b: vec3<f32>, c: vec3<f32>) -> Extent {
    let e = box(a, b, c);
    let p = pad(e.centre, e.half_size);
    return Extent(e.centre, e.half_size + vec3<f32>(p, p, p));
}
