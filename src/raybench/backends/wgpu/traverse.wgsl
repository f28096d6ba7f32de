// kernels/traverse.py: the nearest hit through the BVH (raybench.bvh's
// layout), the same answer as brute.wgsl's loop; the Python docstring says
// why. shader.py fills in the constants' values from raybench.bvh and
// kernels.traverse, so the layout has one definition.

// One row of bvh.nodes, 64 bytes: both children's boxes (lo xyz, hi xyz of
// child 0, then of child 1) and, over the same bytes the builder wrote as
// its int32 `links` view, the children's refs and counts. A struct reads
// each part as its own type, with no bitcast; the boxes as three vec4s, so
// that a row is four wide loads, not sixteen (the walk is bound by issue:
// docs/notes/whitted.md).
struct Node {
    box: array<vec4<f32>, 3>,
    links: vec4<i32>,   // ref 0, ref 1, count 0, count 1
}

// Plane i (0 to 11) of a row's boxes: layout's column i. WGSL-only: the
// Python reads nodes[row, col] (centre_along); a struct's row reads it so.
fn plane(row: i32, i: u32) -> f32 {
    return nodes[row].box[i >> 2u][i & 3u];
}

@group(0) @binding(4) var<storage, read> nodes: array<Node>;
// Binding 5, bvh.ordered, the leaves' spheres: sphere.wgsl's, which reads them.
@group(0) @binding(6) var<storage, read> order: array<i32>;

const STACK: u32 = BVH_STACK;
const INNER: i32 = BVH_INNER;
const PAD: f32 = BVH_PAD;
const TINY: f32 = BVH_TINY;

// One axis of the ray for the slab test (axis_setup's three results).
struct Axis {
    inv: f32,
    lo: f32,   // the origin shifted for the box's low plane, times inv
    hi: f32,   // and for its high one, times inv
}

// The ray's three axes (ray_axes' results).
struct Axes {
    x: Axis,
    y: Axis,
    z: Axis,
}

// A child of the node being visited: its slab interval and its link.
struct Child {
    near: f32,
    far: f32,
    link: i32,    // the child's row where count == INNER, else its first sphere in `ordered`
    count: i32,
}

// A node's two children (children's results).
struct Children {
    a: Child,
    b: Child,
}

// The nearest hit so far: (closest, hit, hit_d) of the Python walk.
struct Nearest {
    closest: f32,
    hit: i32,
    d: f32,
}

// inverse: 1/d for the slab test, finite: |d| raised to at least TINY, its sign kept.
fn inverse(d: f32) -> f32 {
    if (d >= 0.0) {
        return 1.0 / max(d, TINY);
    }
    return 1.0 / min(d, -TINY);
}

// axis_setup: one axis of the ray for the slab test; lo and hi come times
// 1/d: a plane's distance is then one multiply-add (the Python says why).
fn axis_setup(o: f32, d: f32, margin: f32) -> Axis {
    let inv = inverse(d);
    return Axis(inv, (o + margin) * inv, (o - margin) * inv);
}

// slab: (near, far) of the ray through the box of low planes lo and high
// ones hi; near > far where it misses. Both planes of each axis, put in order
// by min and max. The one ray-box test of the WGSL: every walk (walk, the
// packet's nearest_hit_packet) reaches it through children.
fn slab(lo: vec3<f32>, hi: vec3<f32>, x: Axis, y: Axis, z: Axis) -> vec2<f32> {
    let a0 = lo.x * x.inv - x.lo;
    let a1 = lo.y * y.inv - y.lo;
    let a2 = lo.z * z.inv - z.lo;
    let b0 = hi.x * x.inv - x.hi;
    let b1 = hi.y * y.inv - y.hi;
    let b2 = hi.z * z.inv - z.hi;
    let near = max(min(a0, b0), max(min(a1, b1), min(a2, b2)));
    let far = min(max(a0, b0), min(max(a1, b1), max(a2, b2)));
    return vec2<f32>(near, far);
}

// ray_axes: the ray's axes for the slab tests, every box grown by the camera's margin.
fn ray_axes(o: vec3<f32>, dir: vec3<f32>) -> Axes {
    let margin = (abs(o.x) + abs(o.y) + abs(o.z)) * PAD;
    return Axes(axis_setup(o.x, dir.x, margin), axis_setup(o.y, dir.y, margin), axis_setup(o.z, dir.z, margin));
}

// children: a node's two children, the ray's slab through each one's box,
// and their links (read_row's reads: a row as the struct Node's four loads).
fn children(row: i32, axes: Axes) -> Children {
    let p0 = nodes[row].box[0];
    let p1 = nodes[row].box[1];
    let p2 = nodes[row].box[2];
    let links = nodes[row].links;
    let sa = slab(p0.xyz, vec3<f32>(p0.w, p1.x, p1.y), axes.x, axes.y, axes.z);
    let sb = slab(vec3<f32>(p1.z, p1.w, p2.x), p2.yzw, axes.x, axes.y, axes.z);
    return Children(Child(sa.x, sa.y, links.x, links.z), Child(sb.x, sb.y, links.y, links.w));
}

// leaf_test: the exact test on a leaf's primitives (sphere.wgsl's hit_from,
// or hit_ahead_from for the secondary rays, on the primitive as the ray's
// origin sees it: leaf_hit's arithmetic, with the leaf read before the
// order's entry, so that both loads are in flight together, which the
// driver's compiler did not do for a read inside each branch: the walk took
// longer (docs/architecture.md#wgsl)); ties go to the smaller ORIGINAL
// index, which is the one brute force's first-of-smallest-t picks. ahead,
// own, own_inside: the secondary rays' test, where the primitive the ray
// leaves is skipped unless it can meet it again (meets_own).
fn leaf_test(o: vec3<f32>, dir: vec3<f32>, first: i32, count: i32, so_far: Nearest, ahead: bool, own: i32,
             own_inside: bool) -> Nearest {
    var best = so_far;
    for (var j = first; j < first + count; j = j + 1) {
        let seen = from_origin(j, o);
        let original = order[j];
        var td: vec2<f32>;
        if (ahead) {
            if (original == own && !meets_own(own_inside)) {
                continue;
            }
            td = hit_ahead_from(seen, dir, original == own);
        } else {
            td = hit_from(seen, dir);
        }
        if (td.x > 0.0 && (td.x < best.closest || (td.x == best.closest && original < best.hit))) {
            best = Nearest(td.x, original, td.y);
        }
    }
    return best;
}

// What a voted walk pushes for a child its ray does not enter: beyond any
// closest hit (FAR at most), so it never votes to pop that child.
const MISS: f32 = 3.4e38;

// How far along c from the origin the centre of the child box at column col
// lies: the order in which a voted walk takes a node's children, the same
// for all its rays (kernels/traverse.py's centre_along).
fn centre_along(row: i32, col: u32, o: vec3<f32>, c: vec3<f32>) -> f32 {
    return (0.5 * (plane(row, col) + plane(row, col + 3u)) - o.x) * c.x
        + (0.5 * (plane(row, col + 1u) + plane(row, col + 4u)) - o.y) * c.y
        + (0.5 * (plane(row, col + 2u) + plane(row, col + 5u)) - o.z) * c.z;
}

// walk_from: kernels/traverse.py's one walk, for a ray alone or, voted, for
// a subgroup's rays as one packet (VOTED and vote: ray.wgsl or packet.wgsl,
// which the host puts beside this piece). Alone: the nearer child first, the
// nearest sphere with 0 < t < t_max, or with any_hit the first found. Voted:
// a child visited if any ray enters it, the children in the order of their
// centres along the central ray `centre`; every invocation takes part in
// every vote, so a voted walk takes no any_hit.
fn walk_from(o: vec3<f32>, dir: vec3<f32>, centre: vec3<f32>, t_max: f32, any_hit: bool, ahead: bool, own: i32,
             own_inside: bool) -> Found {
    let axes = ray_axes(o, dir);
    var best = Nearest(t_max, -1, 0.0);
    var stack_row: array<i32, STACK>;   // voted, the same in every invocation
    var stack_t: array<f32, STACK>;     // where this invocation's ray enters the node
    var row = 0;
    var top = 0u;
    while (row >= 0) {
        let pair = children(row, axes);
        var a = pair.a;
        var b = pair.b;
        // the nearer child first: its hits can rule the far one out; voted,
        // the one whose centre lies nearer along the central ray
        var b_first = b.near < a.near;
        if (VOTED) {
            b_first = centre_along(row, 6u, o, centre) < centre_along(row, 0u, o, centre);
        }
        if (b_first) {
            let swap = a;
            a = b;
            b = swap;
        }
        let a_in = a.near <= a.far && a.far > 0.0 && a.near <= best.closest;
        // b's box alone here, its entry against the closest hit after a's leaf: tested whole here
        // and again after, the Whitted kernel was measured slower
        // (docs/notes/one-source.md#wgsls-walk-the-second-childs-test-after-the-first-childs-leaf)
        let b_box = b.near <= b.far && b.far > 0.0;
        // voted, both votes at once, before either child's leaf is tested (traverse.py says why)
        let any_a = vote(a_in);
        var any_b = vote(b_box && b.near <= best.closest);
        row = -1;
        if (any_a) {
            if (a.count == INNER) {
                row = a.link;
            } else if (a_in) {
                best = leaf_test(o, dir, a.link, a.count, best, ahead, own, own_inside);
            }
        }
        let b_in = b_box && b.near <= best.closest;  // the first child's hits can rule the second out
        if (!VOTED) {
            any_b = b_in;
        }
        if (any_b) {
            if (b.count != INNER) {
                if (b_in) {
                    best = leaf_test(o, dir, b.link, b.count, best, ahead, own, own_inside);
                }
            } else if (row < 0) {
                row = b.link;
            } else {
                stack_row[top] = b.link;
                if (VOTED) {
                    stack_t[top] = select(MISS, b.near, b_in);
                } else if (!any_hit) {  // a shadow ray's t_max never shrinks: nothing pushed falls behind it
                    stack_t[top] = b.near;
                }
                top = top + 1u;
            }
        }
        if (any_hit && best.hit >= 0) {
            break;
        }
        while (row < 0 && top > 0u) {
            top = top - 1u;
            if (any_hit || vote(stack_t[top] <= best.closest)) {
                row = stack_row[top];
            }
        }
    }
    return Found(best.hit, best.closest, best.d);
}

// walk: the one walk for any ray alone.
fn walk(o: vec3<f32>, dir: vec3<f32>, t_max: f32, any_hit: bool, ahead: bool, own: i32, own_inside: bool) -> Found {
    return walk_from(o, dir, dir, t_max, any_hit, ahead, own, own_inside);
}

// nearest_hit_bvh: walk for the thesis's primary rays.
fn nearest_hit_bvh(o: vec3<f32>, dir: vec3<f32>) -> Hit {
    let found = walk(o, dir, FAR, false, false, -1, false);
    return Hit(found.index, found.d);
}

// nearest_hit: brute.wgsl's signature, so trace.wgsl's main calls either. The tree holds
// exactly the frame's spheres (compute.py builds it for the frame's count),
// so count has nothing left to bound.
fn nearest_hit(o: vec3<f32>, dir: vec3<f32>, count: u32) -> Hit {
    return nearest_hit_bvh(o, dir);
}

// find: whitted.wgsl's search for any ray, through the tree (trace.py's search_tree).
fn find(o: vec3<f32>, dir: vec3<f32>, t_max: f32, any_hit: bool, own: i32, own_inside: bool) -> Found {
    return walk(o, dir, t_max, any_hit, true, own, own_inside);
}
