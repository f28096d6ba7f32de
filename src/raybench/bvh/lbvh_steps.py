"""The LBVH's per-thread steps, written once: Karras's hierarchy row, a
leaf's climb of the bottom-up pass (boxes, SAH costs, the leaves cut), the
treelet step it takes at each row (Karras and Aila 2013) and the reorder
after it. build(...)
compiles them for one target, as kernels.make does for the walks:
numba.cuda.jit(device=True) for the GPU builder (backends/cuda/build.py),
numba.njit or plain Python for the CPU model of its tree (bvh/lbvh_model.py,
the test oracle of both GPU builders). The steps read what other threads
wrote through load_f and load_i (on the GPU atomics that add nothing, past
a stale L1 line; on the CPU plain loads) and count a row's arrivals through
arrive (on the GPU a fence, then an atomic add), so both targets run the
same arithmetic in the same order and build the same tree.
"""

from __future__ import annotations

import types

import numpy as np

from ..layout import BOX_FLOATS, COUNT, INNER, NODE_COST, REF

# A treelet's pieces. Its programme weighs 3^K / 2 splits a row, in local
# arrays of 2^K entries (25 bytes each). The model of this build
# (bvh/lbvh_model.py, benchmarks/archive/gpu_tree_model.py), at 100,000 spheres: SAH
# cost over the host's 1.031 with 6 pieces, 1.026 with 8 (3.6 times the
# splits); pieces kept in their Morton order instead (an interval programme,
# no reorder) gave 1.070 whatever their number.
TREELET = 6
SUBSETS = 1 << TREELET
# A treelet is rebuilt where that lowers its cost below GAIN times what it
# was: rounding alone never changes a tree (all primitives at one point stay a
# balanced tree).
GAIN = np.float32(0.999)
INF = np.float32(np.inf)


def cpu_target(jit) -> types.ModuleType:
    """What make's `target` is on the CPU (numba.cuda on the GPU): a module,
    as numba compiles attributes of modules: `local.array` is np.empty, and
    `clz` counts a uint32's leading zeros, compiled by jit."""
    target = types.ModuleType("lbvh_cpu_target")
    target.local = types.ModuleType("lbvh_cpu_local")
    target.local.array = np.empty
    target.clz = jit(clz32)
    return target


def clz32(x):
    """The leading zero bits of the uint32 x (32 for 0): cuda.clz's answer."""
    if x == 0:
        return 32
    k = 0
    while (x & np.uint32(0x80000000)) == 0:
        x = np.uint32(x << np.uint32(1))
        k += 1
    return k


def cpu_arrive(arrived, row):
    """A child's arrival at row on the CPU, one leaf climbing at a time: the arrivals before it."""
    before = arrived[row]
    arrived[row] = before + 1
    return before


def make(jit, target, load_f, load_i, arrive, primitive) -> types.SimpleNamespace:
    """The steps compiled by jit. target: numba.cuda on the GPU (its
    local.array and clz), cpu_target(jit) on the CPU; load_f and
    load_i read a[i] of a float32 and an int32 array that other threads
    write; arrive(arrived, row) counts a child's arrival at row, its box and
    the rest seen by the sibling first, and returns the arrivals before it.
    primitive: the kind's module (kernels/primitives): the steps see a
    primitive only through its extent (its padded box) and copy_leaf (its
    row of the tree's leaf buffer)."""
    answers = primitive.make(jit)
    extent, copy_leaf = answers.extent, answers.copy_leaf

    @jit
    def delta(keys, n, i, j):
        """Karras's delta: the length of the common prefix of keys i and j (code
        bits, then place bits where the codes are equal); -1 off the ends."""
        if j < 0 or j >= n:
            return -1
        a = keys[i]
        b = keys[j]
        if a != b:
            return target.clz(np.uint32(a ^ b))
        return 32 + target.clz(np.uint32(i ^ j))

    @jit
    def hierarchy_row(keys, n, i, links, up, leaf_up, span):
        """Internal node i (row i): the range of sorted keys it covers, where it
        splits, and its two children (Karras 2012, figure 4): a child of one
        primitive a leaf of it, a child of more the row it starts (collapsed into a
        leaf, or not, by the bottom-up pass, once its box is known). up[row] and
        leaf_up[leaf]: the parent's row times 2 plus the child's slot (the
        root's: -1). span[row]: the first primitive it covers and their count."""
        # the direction of the range: towards the neighbour sharing more bits
        d = 1 if delta(keys, n, i, i + 1) > delta(keys, n, i, i - 1) else -1
        least = delta(keys, n, i, i - d)
        # an upper bound of the range's length, then the length by binary search
        most = 2
        while delta(keys, n, i, i + most * d) > least:
            most *= 2
        length = 0
        step = most // 2
        while step >= 1:
            if delta(keys, n, i, i + (length + step) * d) > least:
                length += step
            step //= 2
        j = i + length * d
        node = delta(keys, n, i, j)
        # the split: the last key sharing more than `node` bits with key i
        split = 0
        step = length
        while True:
            step = (step + 1) // 2
            if delta(keys, n, i, i + (split + step) * d) > node:
                split += step
            if step <= 1:
                break
        gamma = i + split * d + min(d, 0)
        first = min(i, j)
        last = max(i, j)
        span[i, 0] = first
        span[i, 1] = last - first + 1
        if first == gamma:
            links[i, REF] = first
            links[i, COUNT] = 1
            leaf_up[gamma] = 2 * i
        else:
            links[i, REF] = gamma
            links[i, COUNT] = INNER
            up[gamma] = 2 * i
        if last == gamma + 1:
            links[i, REF + 1] = gamma + 1
            links[i, COUNT + 1] = 1
            leaf_up[gamma + 1] = 2 * i + 1
        else:
            links[i, REF + 1] = gamma + 1
            links[i, COUNT + 1] = INNER
            up[gamma + 1] = 2 * i + 1
        if i == 0:
            up[0] = -1

    @jit
    def half_area(lx, ly, lz, hx, hy, hz):
        dx, dy, dz = max(hx - lx, np.float32(0)), max(hy - ly, np.float32(0)), max(hz - lz, np.float32(0))
        return dx * dy + dy * dz + dz * dx

    @jit
    def put_box(nodes, row, col, lx, ly, lz, hx, hy, hz):
        """A child's box into its row's slot at column col."""
        nodes[row, col] = lx
        nodes[row, col + 1] = ly
        nodes[row, col + 2] = lz
        nodes[row, col + 3] = hx
        nodes[row, col + 4] = hy
        nodes[row, col + 5] = hz

    @jit
    def entry(nodes, links, span, kid, below, costs, row, slot, e, tb, tn, tc, th, tw, tref, tcnt, trow):
        """Piece e of a treelet: child slot of row (its box, link, row below,
        cost, height, rows below, primitives), read through load_f and load_i:
        other threads wrote them, and on a GPU a plain load could find a
        stale line in this SM's L1."""
        link = 2 * row + slot
        for q in range(6):
            tb[e, q] = load_f(nodes, (row, 6 * slot + q))
        tref[e] = load_i(links, (row, REF + slot))
        tcnt[e] = load_i(links, (row, COUNT + slot))
        trow[e] = load_i(kid, link)
        tc[e] = load_f(costs, link)
        th[e] = load_i(below, 2 * link)
        tw[e] = load_i(below, 2 * link + 1)
        tn[e] = load_i(span, (trow[e], 1)) if trow[e] >= 0 else 1

    @jit
    def union(tb, part, size):
        """The box of the pieces in the bit set part."""
        lx = ly = lz = INF
        hx = hy = hz = -INF
        for e in range(size):
            if part & (1 << e):
                lx, ly, lz = min(lx, tb[e, 0]), min(ly, tb[e, 1]), min(lz, tb[e, 2])
                hx, hy, hz = max(hx, tb[e, 3]), max(hy, tb[e, 4]), max(hz, tb[e, 5])
        return lx, ly, lz, hx, hy, hz

    @jit
    def piece(part):
        """The piece of a set of one."""
        e = 0
        while (1 << e) != part:
            e += 1
        return e

    @jit
    def treelet(x, old, nodes, links, span, up, leaf_up, kid, below, costs, leaf_max):
        """Row x's subtree (its rows' boxes, links and costs final) made the
        cheapest tree over its treelet (Karras and Aila 2013): x's two
        children, then, up to TREELET pieces, the piece of largest area that is
        a row (not a leaf) replaced by its two children. The cheapest binary
        tree over the pieces, in any order, by a programme over their subsets
        (bit sets, each after its own subsets in numeric order: its box's half
        area, primitives, cost, best split into two, whether a leaf, and as a child
        its height and the rows a walk reaches below it); a set of primitives is
        cut into a leaf as the bottom-up pass cuts. The rows the treelet frees (x's and
        the replaced ones) hold the new tree: links, boxes, counts, costs and
        links up written here. A leaf's primitives are now no range of the sort's
        order: reorder_one puts them in tree order and sets the leaves' refs.
        x is changed only where the cost falls below GAIN times old (x's cost
        as it is), so that rounding never churns equal trees. Returns (cost,
        height, rows) of x after, or (old, -1, -1) where nothing changed."""
        K = TREELET
        tb = target.local.array((TREELET, 6), np.float32)
        tn = target.local.array(TREELET, np.int32)
        tc = target.local.array(TREELET, np.float32)
        th = target.local.array(TREELET, np.int32)
        tw = target.local.array(TREELET, np.int32)
        tref = target.local.array(TREELET, np.int32)
        tcnt = target.local.array(TREELET, np.int32)
        trow = target.local.array(TREELET, np.int32)
        rows = target.local.array(TREELET, np.int32)
        area = target.local.array(SUBSETS, np.float32)
        cnt = target.local.array(SUBSETS, np.int32)
        cost = target.local.array(SUBSETS, np.float32)
        split = target.local.array(SUBSETS, np.int32)
        hh = target.local.array(SUBSETS, np.int32)
        ww = target.local.array(SUBSETS, np.int32)
        leaf = target.local.array(SUBSETS, np.int8)
        stack = target.local.array((TREELET, 2), np.int32)
        rows[0] = x
        used = 1
        entry(nodes, links, span, kid, below, costs, x, 0, 0, tb, tn, tc, th, tw, tref, tcnt, trow)
        entry(nodes, links, span, kid, below, costs, x, 1, 1, tb, tn, tc, th, tw, tref, tcnt, trow)
        size = 2
        while size < K:
            best = -1
            best_area = np.float32(-1)
            for e in range(size):
                if tcnt[e] == INNER:
                    ar = half_area(tb[e, 0], tb[e, 1], tb[e, 2], tb[e, 3], tb[e, 4], tb[e, 5])
                    if ar > best_area:
                        best_area = ar
                        best = e
            if best < 0:
                break
            r = tref[best]
            rows[used] = r
            used += 1
            entry(nodes, links, span, kid, below, costs, r, 0, best, tb, tn, tc, th, tw, tref, tcnt, trow)
            entry(nodes, links, span, kid, below, costs, r, 1, size, tb, tn, tc, th, tw, tref, tcnt, trow)
            size += 1
        if size < 3:
            return old, -1, -1
        full = (1 << size) - 1
        for sm in range(1, full + 1):
            low = sm & -sm
            if sm == low:
                e = piece(sm)
                cnt[sm] = tn[e]
                cost[sm] = tc[e]
                hh[sm] = th[e]
                ww[sm] = tw[e]
                continue
            lx, ly, lz, hx, hy, hz = union(tb, sm, size)
            area[sm] = half_area(lx, ly, lz, hx, hy, hz)
            cnt[sm] = cnt[low] + cnt[sm ^ low]
            best = INF
            at = low
            p = (sm - 1) & sm
            while p > 0:
                if p & low:  # each split once: the side with the lowest piece first
                    v = cost[p] + cost[sm ^ p]
                    if v < best:
                        best = v
                        at = p
                p = (p - 1) & sm
            inner = NODE_COST * area[sm] + best
            split[sm] = at
            lc = np.float32(cnt[sm]) * area[sm]
            if sm != full and cnt[sm] <= leaf_max and lc <= inner:
                cost[sm] = lc
                leaf[sm] = 1
                hh[sm] = 0
                ww[sm] = 0
            else:
                cost[sm] = inner
                leaf[sm] = 0
                hh[sm] = 1 + max(hh[at], hh[sm ^ at])
                ww[sm] = 1 + ww[at] + ww[sm ^ at]
        if not cost[full] < old * GAIN:
            return old, -1, -1
        stack[0, 0] = full
        stack[0, 1] = x
        top = 1
        used = 1
        while top > 0:
            top -= 1
            sm = stack[top, 0]
            row = stack[top, 1]
            for slot in range(2):
                part = split[sm] if slot == 0 else sm ^ split[sm]
                link = 2 * row + slot
                col = 6 * slot
                if part & (part - 1) == 0:  # a piece: as it was, under a new parent
                    e = piece(part)
                    for q in range(6):
                        nodes[row, col + q] = tb[e, q]
                    links[row, REF + slot] = tref[e]
                    links[row, COUNT + slot] = tcnt[e]
                    kid[link] = trow[e]
                    costs[link] = tc[e]
                    below[2 * link] = th[e]
                    below[2 * link + 1] = tw[e]
                    if trow[e] >= 0:
                        up[trow[e]] = link
                    else:
                        leaf_up[tref[e]] = link
                    continue
                child = rows[used]
                used += 1
                lx, ly, lz, hx, hy, hz = union(tb, part, size)
                put_box(nodes, row, col, lx, ly, lz, hx, hy, hz)
                span[child, 0] = -1  # no range of the sort's order
                span[child, 1] = cnt[part]
                kid[link] = child
                up[child] = link
                costs[link] = cost[part]
                below[2 * link] = hh[part]
                below[2 * link + 1] = ww[part]
                if leaf[part] != 0:
                    links[row, REF + slot] = -1  # set by reorder_one
                    links[row, COUNT + slot] = cnt[part]
                else:
                    links[row, REF + slot] = child
                    links[row, COUNT + slot] = INNER
                stack[top, 0] = part
                stack[top, 1] = child
                top += 1
        return cost[full], hh[full], ww[full]

    @jit
    def reorder_one(items, k, order, leaf_up, up, links, kid, span, order_out, leaf_up_out, ordered):
        """After treelets, primitive k of the sort's order put in the tree's order, so
        that every leaf is again a range of them: leaf k's place is the primitives
        left of it in the tree (on its way up, the left sibling's count wherever
        it is a right child). Its primitive, its index and its link up go there; on
        the way up while it is the leftmost primitive of the child it climbs from,
        it sets that child's ref where the child is a leaf (every leaf has one
        leftmost primitive)."""
        rank = 0
        link = leaf_up[k]
        while link >= 0:
            row = link // 2
            if link - 2 * row == 1:
                left = kid[2 * row]
                rank += span[left, 1] if left >= 0 else 1
            link = up[row]
        s = order[k]
        order_out[rank] = s
        leaf_up_out[rank] = leaf_up[k]
        copy_leaf(items, s, ordered, rank)
        link = leaf_up[k]
        while link >= 0:
            row = link // 2
            slot = link - 2 * row
            if links[row, COUNT + slot] != INNER:
                links[row, REF + slot] = rank
            if slot == 1:
                break
            link = up[row]

    @jit
    def climb(
        items, k, order, leaf_up, up, span, nodes, links, below, costs, kid, arrived, ordered, stats, cost,
        leaf_max, sah, restructure,
    ):  # fmt: skip
        """Leaf k (its primitive order[k]) climbs to the root, each row's box
        written into its parent's slot; a row's second child to arrive (arrived
        counts them) unites the two boxes and climbs on, and sets the counter
        back to 0 for the next pass. Also writes leaf k's primitive into ordered
        (the scene's values).

        On the way up, per child (index 2 * row + slot), what the walks see below
        it: below[2 * index] its height (a leaf 0, a row 1 + its children's
        most), below[2 * index + 1] the rows a walk reaches from it (a leaf 0),
        costs[index] its SAH cost unnormalised (a leaf: count x its box's half
        area; a row: NODE_COST x its half area plus its children's); stats: the
        root's height and rows, cost[0] the tree's SAH cost (bvh.cost.sah_cost's),
        written by the leaf that reaches the root.

        leaf_max > 0 (a build): the second arrival at a row of at most leaf_max
        primitives makes it a leaf of them in its parent's slot (they are
        consecutive: an LBVH row covers a range of the leaf order) where sah is
        0, or where sah is 1 and the SAH says a leaf is cheaper than the row
        with the best choice below it (a leaf's cost against the row's: the
        optimal cut of this tree into leaves, as each row's cost is the cheapest
        of its subtree's). Its rows stay, out of the walks' reach, so that
        refits still climb through them. Where restructure is 1, each row's
        subtree is first made the cheapest over its treelet (treelet; kid[index]
        is the row below each child, -1 for a primitive). leaf_max == 0 (a refit):
        the links are kept, and the costs are the tree's as it is."""
        s = order[k]
        copy_leaf(items, s, ordered, k)
        cx, cy, cz, ex, ey, ez = extent(items, s)
        lx, ly, lz, hx, hy, hz = cx - ex, cy - ey, cz - ez, cx + ex, cy + ey, cz + ez
        h = 0
        w = 0
        c = half_area(lx, ly, lz, hx, hy, hz)  # a leaf of one primitive
        a = c
        cur = -1
        link = leaf_up[k]
        while link >= 0:
            row = link // 2
            slot = link - 2 * row
            col = slot * BOX_FLOATS
            put_box(nodes, row, col, lx, ly, lz, hx, hy, hz)
            below[2 * link] = h
            below[2 * link + 1] = w
            costs[link] = c
            kid[link] = cur
            if arrive(arrived, row) == 0:
                return  # the sibling, arriving second, goes on
            other = (1 - slot) * BOX_FLOATS
            sib = 2 * row + 1 - slot
            lx = min(lx, load_f(nodes, (row, other)))
            ly = min(ly, load_f(nodes, (row, other + 1)))
            lz = min(lz, load_f(nodes, (row, other + 2)))
            hx = max(hx, load_f(nodes, (row, other + 3)))
            hy = max(hy, load_f(nodes, (row, other + 4)))
            hz = max(hz, load_f(nodes, (row, other + 5)))
            h = 1 + max(h, load_i(below, 2 * sib))
            w = 1 + w + load_i(below, 2 * sib + 1)
            # the two children's sum first: the same whichever arrived first
            a = half_area(lx, ly, lz, hx, hy, hz)
            c = NODE_COST * a + (c + load_f(costs, sib))
            arrived[row] = 0
            cur = row
            if restructure != 0 and leaf_max > 0 and span[row, 1] > 2:  # two primitives have one tree
                tc, th, tw = treelet(row, c, nodes, links, span, up, leaf_up, kid, below, costs, leaf_max)
                if th >= 0:
                    c, h, w = tc, th, tw
            link = up[row]
            if link >= 0:
                parent = link // 2
                pslot = link - 2 * parent
                count = span[row, 1]
                leaf = np.float32(count) * a
                if count <= leaf_max and (sah == 0 or leaf <= c):
                    links[parent, REF + pslot] = span[row, 0]
                    links[parent, COUNT + pslot] = count
                if links[parent, COUNT + pslot] != INNER:
                    h = 0
                    w = 0
                    c = leaf
        stats[0] = h
        stats[1] = w
        cost[0] = c / a if a > 0 else np.float32(0)

    return types.SimpleNamespace(
        extent=extent,
        climb=climb,
        delta=delta,
        hierarchy_row=hierarchy_row,
        half_area=half_area,
        entry=entry,
        union=union,
        piece=piece,
        treelet=treelet,
        reorder_one=reorder_one,
    )
