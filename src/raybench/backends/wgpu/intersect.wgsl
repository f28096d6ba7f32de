// kernels/intersect.py's intersect_relative: same formulas, same order.
// (e, r): the sphere's centre minus the ray's origin, and its radius; d: the
// unit ray. Returns (t, d), t = -1 on a miss. disc = r^2 - |EO - v dir|^2
// rather than the thesis's r^2 - (EO.EO - v^2), which loses every digit for
// small, far spheres in float32 (the Python docstring says why).
// chord: (v, disc), v = EO.dir and disc = r^2 - |EO - v dir|^2.
fn chord(ex: f32, ey: f32, ez: f32, r: f32, dx: f32, dy: f32, dz: f32) -> vec2<f32> {
    let v = ex * dx + ey * dy + ez * dz;
    let px = ex - v * dx;
    let py = ey - v * dy;
    let pz = ez - v * dz;
    return vec2<f32>(v, r * r - (px * px + py * py + pz * pz));
}

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

fn intersect_sphere(o: vec3<f32>, dir: vec3<f32>, s: Sphere) -> vec2<f32> {
    return intersect_relative(s.cx - o.x, s.cy - o.y, s.cz - o.z, s.r, dir.x, dir.y, dir.z);
}
