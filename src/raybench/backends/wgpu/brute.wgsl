// On lavapipe (Mesa's CPU Vulkan) one invocation runs at most 65,535 trips
// of a loop (gallivm's loop limiter): a Whitted pixel of many rays over 1,000
// spheres reaches it and is cut short, so there brute force is exact only for
// small scenes (measured: 300 spheres exact, 1,000 not, at depth 5); GPUs
// have no such limit, and the BVH's walks stay far under it.
//
// kernels/trace.py's scan: every sphere in order, the thesis's loop, for any
// ray: the smallest 0 < t < t_max wins; strict < keeps the first sphere on a
// tie; any_hit stops at the first; ahead, own, own_inside: the secondary
// rays' test (traverse.py's leaf_test), sphere.wgsl's hit_ahead, else its
// hit. Returns (index or -1, t, d).
fn scan(o: vec3<f32>, dir: vec3<f32>, count: u32, t_max: f32, any_hit: bool, ahead: bool, own: i32,
        own_inside: bool) -> Found {
    var best = Found(-1, t_max, 0.0);
    for (var i = 0u; i < count; i = i + 1u) {
        var td: vec2<f32>;
        if (ahead) {
            if (i32(i) == own && !meets_own(own_inside)) {
                continue;
            }
            td = hit_ahead(i32(i), o, dir, i32(i) == own);
        } else {
            td = hit(i32(i), o, dir);
        }
        if (td.x < best.t && td.x > 0.0) {
            best = Found(i32(i), td.x, td.y);
            if (any_hit) {
                break;
            }
        }
    }
    return best;
}

// nearest_hit: kernels/trace.py's, scan for the thesis's primary rays.
// An acceleration structure (traverse.wgsl) is another piece with this signature.
fn nearest_hit(o: vec3<f32>, dir: vec3<f32>, count: u32) -> Hit {
    let found = scan(o, dir, count, FAR, false, false, -1, false);
    return Hit(found.index, found.d);
}

// find: whitted.wgsl's search for any ray, by brute force (trace.py's search_all).
fn find(o: vec3<f32>, dir: vec3<f32>, t_max: f32, any_hit: bool, own: i32, own_inside: bool) -> Found {
    return scan(o, dir, frame.count, t_max, any_hit, true, own, own_inside);
}
