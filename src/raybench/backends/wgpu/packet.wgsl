// backends/cuda/program.py's _bvh_packet_kernel: the BVH walk with a subgroup's rays
// as one packet, which visits a node if any of its rays enters it; each ray
// tests only the leaves it enters itself, so the pixels are those of
// nearest_hit_bvh. The votes are subgroup operations, the same in every
// invocation of the subgroup, so the node, the stack and every branch are
// too: one fetch of a node serves the subgroup, which never diverges. Needs
// the adapter's "subgroup" feature; a workgroup of several subgroups walks as
// that many packets, each as correct as one. Only where asked for (walk
// "packet"): on the GPU measured through Vulkan it was slower than a ray at a
// time (compute.py says where that is measured).

// The walk voted (traverse.wgsl's walk_from): a subgroup's rays as one packet.
const VOTED: bool = true;

fn vote(p: bool) -> bool {
    return subgroupAny(p);
}

// nearest_hit_packet: the thesis's primary ray through the voted walk, the
// children ordered along the workgroup's central ray.
fn nearest_hit_packet(o: vec3<f32>, dir: vec3<f32>, centre: vec3<f32>) -> Hit {
    let found = walk_from(o, dir, centre, FAR, false, false, -1, false);
    return Hit(found.index, found.d);
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
