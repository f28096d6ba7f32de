// backends/cuda/tracer.py's _bvh_packet_kernel: the BVH walk with a subgroup's rays
// as one packet, which visits a node if any of its rays enters it; each ray
// tests only the leaves it enters itself, so the pixels are those of
// nearest_hit_bvh. The votes are subgroup operations, the same in every
// invocation of the subgroup, so the node, the stack and every branch are
// too: one fetch of a node serves the subgroup, which never diverges. Needs
// the adapter's "subgroup" feature; a workgroup of several subgroups walks as
// that many packets, each as correct as one. Only where asked for (walk
// "packet"): on the GPU measured through Vulkan it was slower than a ray at a
// time (compute.py says where that is measured).

// What an invocation pushes for a child its ray does not enter: beyond any
// closest hit (FAR at most), so it never votes to pop that child.
const MISS: f32 = 3.4e38;

// How far along c from the origin the centre of the child box at column col
// lies: the order in which the packet takes a node's children, the same for
// all its rays (kernels/traverse.py's centre_along).
fn centre_along(row: i32, col: u32, o: vec3<f32>, c: vec3<f32>) -> f32 {
    return (0.5 * (plane(row, col) + plane(row, col + 3u)) - o.x) * c.x
        + (0.5 * (plane(row, col + 1u) + plane(row, col + 4u)) - o.y) * c.y
        + (0.5 * (plane(row, col + 2u) + plane(row, col + 5u)) - o.z) * c.z;
}

// nearest_hit_packet: the CUDA kernel's walk (no Python twin of one ray's
// share of a subgroup's packet: the CPU's packets, kernels/packets.py, hold
// all of a packet's rays in one thread).
fn nearest_hit_packet(o: vec3<f32>, dir: vec3<f32>, centre: vec3<f32>) -> Hit {
    let axes = ray_axes(o, dir);
    var best = Nearest(FAR, -1, 0.0);
    var stack_row: array<i32, STACK>;   // the same in every invocation
    var stack_t: array<f32, STACK>;     // where this invocation's ray enters the node
    var row = 0;
    var top = 0u;
    while (row >= 0) {
        let pair = children(row, axes);
        var a = pair.a;
        var b = pair.b;
        var a_in = a.near <= a.far && a.far > 0.0 && a.near <= best.closest;
        var b_in = b.near <= b.far && b.far > 0.0 && b.near <= best.closest;
        var any_a = subgroupAny(a_in);
        var any_b = subgroupAny(b_in);
        if (centre_along(row, 6u, o, centre) < centre_along(row, 0u, o, centre)) {
            let child = a;
            a = b;
            b = child;
            let enters = a_in;
            a_in = b_in;
            b_in = enters;
            let any = any_a;
            any_a = any_b;
            any_b = any;
        }
        row = -1;
        if (any_a) {
            if (a.count == INNER) {
                row = a.link;
            } else if (a_in) {
                best = leaf_hits(o, dir, a.link, a.count, best);
            }
        }
        if (any_b) {
            if (b.count != INNER) {
                if (b_in && b.near <= best.closest) {
                    best = leaf_hits(o, dir, b.link, b.count, best);
                }
            } else if (row < 0) {
                row = b.link;
            } else {
                stack_row[top] = b.link;
                stack_t[top] = select(MISS, b.near, b_in);
                top = top + 1u;
            }
        }
        while (row < 0 && top > 0u) {
            top = top - 1u;
            if (subgroupAny(stack_t[top] <= best.closest)) {
                row = stack_row[top];
            }
        }
    }
    return Hit(best.hit, best.d);
}

// trace.wgsl's main for the packet walk: every invocation takes part in every
// vote; those off the image trace a copy of its last row or column, unstored.
@compute @workgroup_size(WORKGROUP_X, WORKGROUP_Y)
fn main_packet(@builtin(global_invocation_id) id: vec3<u32>, @builtin(workgroup_id) group: vec3<u32>) {
    let dir = primary_ray(min(id.x, frame.width - 1u), min(id.y, frame.height - 1u));
    // the workgroup's central ray: the order of the children, the same for all its subgroups
    let centre = primary_ray(min(group.x * WORKGROUP_X + WORKGROUP_X / 2u, frame.width - 1u),
                             min(group.y * WORKGROUP_Y + WORKGROUP_Y / 2u, frame.height - 1u));
    let hit = nearest_hit_packet(frame.origin.xyz, dir, centre);
    if (id.x < frame.width && id.y < frame.height) {
        store_pixel(id.x, id.y, hit);
    }
}
