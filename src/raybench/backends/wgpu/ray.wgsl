// The walk for a ray alone (traverse.wgsl's walk_from): each vote is the
// ray's own answer. The host puts this piece beside traverse.wgsl, or
// packet.wgsl for the voted walk.
const VOTED: bool = false;

fn vote(p: bool) -> bool {
    return p;
}
