// kernels/trace.py's nearest_hit: every sphere in order, the thesis's loop.
// The smallest t > 0 wins; strict < keeps the first sphere on a tie.
// Returns the index (-1: none) and the winner's half-chord d.
// An acceleration structure (a BVH) would be another piece with this signature.
fn nearest_hit(o: vec3<f32>, dir: vec3<f32>, count: u32) -> Hit {
    var closest = FAR;
    var best = Hit(-1, 0.0);
    for (var i = 0u; i < count; i = i + 1u) {
        let td = intersect_sphere(o, dir, spheres[i]);
        if (td.x < closest && td.x > 0.0) {
            closest = td.x;
            best = Hit(i32(i), td.y);
        }
    }
    return best;
}
