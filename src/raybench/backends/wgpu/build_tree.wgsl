// Steps 4 and 5 of the build (cuda_build._hierarchy, _bounds_up), and the
// refit: Karras's rows from the sorted codes, then the boxes bottom-up, the
// leaves cut where the SAH says, each row's height and cost.
//
// Rows are written in raybench.bvh's layout (layout.py): 16 words a row,
// the children's boxes (words 0-5 and 6-11) and their links (REF + slot,
// COUNT + slot), all through atomics (the walk reads the same bytes).
//
// The bottom-up pass hands values between invocations of different
// workgroups: the first child to arrive at a row writes its box, height,
// rows and cost, the second reads them. WGSL's atomics are relaxed and it
// has no fence across workgroups (cuda's threadfence), so nothing orders the
// first's writes before its count: the second could see the count and not
// yet the box. Each such word therefore starts UNSET (written in the dispatch
// before, whose writes every later dispatch sees) and the second waits for
// each word to leave UNSET: a single word's atomics are coherent, and the
// first has written it before it counted. The values are floats too, so
// they travel as their bits in u32 atomics (WGSL has no float atomics).

// binding 1, the primitives' buffer `items`, with extent and leaf_row: the
// primitive's piece (sphere_build.wgsl)
@group(0) @binding(2) var<storage, read> keys: array<u32>;           // the sorted codes
@group(0) @binding(3) var<storage, read> order: array<u32>;          // their spheres
@group(0) @binding(4) var<storage, read_write> nodes: array<atomic<u32>>;
// up[row] (from 0), leaf_up[k] (from m), span[row] (from m + n: the first
// sphere and their count): a link up is the parent's row times 2 plus the
// child's slot.
@group(0) @binding(5) var<storage, read_write> links: array<u32>;
// below[2 * link + 0/1] (from 0): the child's height and rows reached;
// costs[link] (from 4m): its SAH cost; arrived[row] (from 6m).
@group(0) @binding(6) var<storage, read_write> scratch: array<atomic<u32>>;
@group(0) @binding(7) var<storage, read_write> ordered: array<Leaf>;
// the root's height and rows reached, the tree's cost unnormalised and its
// root's half area (the host divides: WGSL's division is not exact)
@group(0) @binding(8) var<storage, read_write> stats: array<u32, 4>;

fn rows() -> u32 {
    return params.n - 1u;
}

// Karras's delta: the length of the common prefix of keys i and j (code
// bits, then place bits where the codes are equal); -1 off the ends.
fn delta(i: i32, j: i32) -> i32 {
    if (j < 0 || j >= i32(params.n)) {
        return -1;
    }
    let a = keys[i];
    let b = keys[j];
    if (a != b) {
        return i32(countLeadingZeros(a ^ b));
    }
    return 32 + i32(countLeadingZeros(u32(i ^ j)));
}

// Row `row`'s words that the bottom-up pass hands on set UNSET, its count
// of arrivals 0.
fn unset(row: u32) {
    let m = rows();
    for (var q = 0u; q < 12u; q = q + 1u) {
        atomicStore(&nodes[NODE_WORDS * row + q], UNSET);
    }
    for (var q = 0u; q < 4u; q = q + 1u) {
        atomicStore(&scratch[4u * row + q], UNSET);
    }
    atomicStore(&scratch[4u * m + 2u * row], UNSET);
    atomicStore(&scratch[4u * m + 2u * row + 1u], UNSET);
    atomicStore(&scratch[6u * m + row], 0u);
}

fn set_child(i: u32, slot: u32, child: u32, count: i32) {
    atomicStore(&nodes[NODE_WORDS * i + REF + slot], child);
    atomicStore(&nodes[NODE_WORDS * i + COUNT + slot], bitcast<u32>(count));
}

// Internal node i (row i): the range of sorted keys it covers, where it
// splits, its two children (a child of one sphere a leaf of it, of more
// the row it starts), as cuda_build._hierarchy; and its words unset.
@compute @workgroup_size(THREADS)
fn hierarchy(@builtin(workgroup_id) wg: vec3<u32>, @builtin(num_workgroups) groups: vec3<u32>,
             @builtin(local_invocation_index) t: u32) {
    let row = element(wg, groups, t);
    if (row >= rows()) {
        return;
    }
    unset(row);
    let i = i32(row);
    let m = rows();
    let n = params.n;
    // the direction of the range: towards the neighbour sharing more bits
    let d = select(-1, 1, delta(i, i + 1) > delta(i, i - 1));
    let least = delta(i, i - d);
    // an upper bound of the range's length, then the length by binary search
    var most = 2;
    while (delta(i, i + most * d) > least) {
        most = most * 2;
    }
    var length = 0;
    for (var step = most / 2; step >= 1; step = step / 2) {
        if (delta(i, i + (length + step) * d) > least) {
            length = length + step;
        }
    }
    let j = i + length * d;
    let node = delta(i, j);
    // the split: the last key sharing more than `node` bits with key i
    var split = 0;
    var step = length;
    loop {
        step = (step + 1) / 2;
        if (delta(i, i + (split + step) * d) > node) {
            split = split + step;
        }
        if (step <= 1) {
            break;
        }
    }
    let gamma = u32(i + split * d + min(d, 0));
    let first = u32(min(i, j));
    let last = u32(max(i, j));
    links[m + n + 2u * row] = first;
    links[m + n + 2u * row + 1u] = last - first + 1u;
    if (first == gamma) {
        set_child(row, 0u, gamma, 1);
        links[m + gamma] = 2u * row;
    } else {
        set_child(row, 0u, gamma, INNER);
        links[gamma] = 2u * row;
    }
    if (last == gamma + 1u) {
        set_child(row, 1u, gamma + 1u, 1);
        links[m + gamma + 1u] = 2u * row + 1u;
    } else {
        set_child(row, 1u, gamma + 1u, INNER);
        links[gamma + 1u] = 2u * row + 1u;
    }
    if (row == 0u) {
        links[0] = NONE;
    }
}

// Before a refit: every row's words unset (a build's hierarchy does it).
@compute @workgroup_size(THREADS)
fn reset(@builtin(workgroup_id) wg: vec3<u32>, @builtin(num_workgroups) groups: vec3<u32>,
         @builtin(local_invocation_index) t: u32) {
    let row = element(wg, groups, t);
    if (row < rows()) {
        unset(row);
    }
}

// nodes[i] once the invocation that wrote it has (see the top).
fn await_node(i: u32) -> u32 {
    var v = atomicLoad(&nodes[i]);
    while (v == UNSET) {
        v = atomicLoad(&nodes[i]);
    }
    return v;
}

fn await_scratch(i: u32) -> u32 {
    var v = atomicLoad(&scratch[i]);
    while (v == UNSET) {
        v = atomicLoad(&scratch[i]);
    }
    return v;
}

fn half_area(lo: vec3<f32>, hi: vec3<f32>) -> f32 {
    let d = max(hi - lo, vec3<f32>(0.0));
    return (exact(d.x * d.y) + exact(d.y * d.z)) + exact(d.z * d.x);
}

// Leaf k (its sphere order[k]) climbs to the root, as cuda_build._bounds_up
// (its docstring says what each value is): each row's box written into its
// parent's slot; the second child to arrive at a row unites the two boxes,
// sums the costs, and climbs on. leaf_max > 0 (a build): a row of at most
// leaf_max spheres becomes a leaf in its parent's slot where sah is 0, or
// where the SAH says a leaf is no costlier than the row. leaf_max == 0 (a
// refit): the links are kept. Also writes leaf k's sphere into ordered.
@compute @workgroup_size(THREADS)
fn bounds_up(@builtin(workgroup_id) wg: vec3<u32>, @builtin(num_workgroups) groups: vec3<u32>,
             @builtin(local_invocation_index) t: u32) {
    let k = element(wg, groups, t);
    let n = params.n;
    if (k >= n) {
        return;
    }
    let m = rows();
    let item = order[k];
    ordered[k] = leaf_row(item);
    let box = extent(item);
    var lo = box.centre - box.half_size;
    var hi = box.centre + box.half_size;
    var h = 0u;
    var w = 0u;
    var c = half_area(lo, hi);  // a leaf of one sphere
    var a = c;
    var link = links[m + k];
    while (link != NONE) {
        let row = link / 2u;
        let slot = link - 2u * row;
        let col = NODE_WORDS * row + BOX_WORDS * slot;
        atomicStore(&nodes[col], bitcast<u32>(lo.x));
        atomicStore(&nodes[col + 1u], bitcast<u32>(lo.y));
        atomicStore(&nodes[col + 2u], bitcast<u32>(lo.z));
        atomicStore(&nodes[col + 3u], bitcast<u32>(hi.x));
        atomicStore(&nodes[col + 4u], bitcast<u32>(hi.y));
        atomicStore(&nodes[col + 5u], bitcast<u32>(hi.z));
        atomicStore(&scratch[2u * link], h);
        atomicStore(&scratch[2u * link + 1u], w);
        atomicStore(&scratch[4u * m + link], bitcast<u32>(c));
        if (atomicAdd(&scratch[6u * m + row], 1u) == 0u) {
            return;  // the sibling, arriving second, goes on
        }
        let other = NODE_WORDS * row + BOX_WORDS * (1u - slot);
        let sib = 2u * row + 1u - slot;
        lo = min(lo, vec3<f32>(bitcast<f32>(await_node(other)), bitcast<f32>(await_node(other + 1u)),
                               bitcast<f32>(await_node(other + 2u))));
        hi = max(hi, vec3<f32>(bitcast<f32>(await_node(other + 3u)), bitcast<f32>(await_node(other + 4u)),
                               bitcast<f32>(await_node(other + 5u))));
        h = 1u + max(h, await_scratch(2u * sib));
        w = 1u + w + await_scratch(2u * sib + 1u);
        // the two children's sum first: the same whichever arrived first
        a = half_area(lo, hi);
        c = exact(NODE_COST * a) + (c + bitcast<f32>(await_scratch(4u * m + sib)));
        link = links[row];
        if (link != NONE) {
            let parent = link / 2u;
            let pslot = link - 2u * parent;
            let count = links[m + n + 2u * row + 1u];
            let leaf = exact(f32(count) * a);
            if (count <= params.leaf_max && (params.sah == 0u || leaf <= c)) {
                set_child(parent, pslot, links[m + n + 2u * row], i32(count));
            }
            if (bitcast<i32>(atomicLoad(&nodes[NODE_WORDS * parent + COUNT + pslot])) != INNER) {
                h = 0u;
                w = 0u;
                c = leaf;
            }
        }
    }
    stats[0] = h;
    stats[1] = w;
    stats[2] = bitcast<u32>(c);
    stats[3] = bitcast<u32>(a);
}
