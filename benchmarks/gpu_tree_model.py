"""A CPU model of the tree that backends/cuda/build.py builds on the GPU: the
same Morton codes, the same stable order, Karras's hierarchy, the same
bottom-up pass (boxes, SAH costs, the leaves it cuts, the treelets it
rebuilds) and reorder, in the same float32 arithmetic, written with NumPy and Numba's CPU compiler. Under numba's CUDA
simulator it gives the kernels' tree bit for bit (tests/test_cuda_build.py
checks it), as it gives the WGSL port's, backends/wgpu/build.py's, on
lavapipe (tests/test_wgpu_build.py); here it gives the SAH cost of the GPU's trees at sizes the
simulator cannot build (100,000 and 1,000,000 spheres) on a machine with no
GPU. A GPU may fuse multiply-adds where the model does not, which can tip
a leaf's choice where two costs tie to the last bit; the cost is the same to
a few float32 epsilons.

    python benchmarks/gpu_tree_model.py [--spheres 1000 --spheres 100000] [--quality sah --quality treelet]

prints, per sphere count and quality, the SAH cost of the model's tree over
the host's binned SAH tree (raybench.bvh), as one JSON line each.
"""

from __future__ import annotations

import argparse
import json
import sys
import time

import numba
import numpy as np

from raybench import bvh, layout
from raybench.backends.cuda import build as cuda_build
from raybench.bvh import cost as tree_cost

AXIS_CELLS = cuda_build.AXIS_CELLS
PAD = layout.PAD
NODE_COST = bvh.NODE_COST
INNER = layout.INNER
REF = layout.REF
COUNT = layout.COUNT


def morton(spheres: np.ndarray) -> np.ndarray:
    """Each centre's 30-bit Morton code in the centres' box (cuda_build._morton's arithmetic)."""
    n = spheres.shape[1]
    code = np.zeros(n, np.int64)
    for a in range(3):
        c = spheres[a]
        lo, hi = c.min(), c.max()
        cells = np.zeros(n, np.int64)
        if hi > lo:
            cells = np.minimum(((c - lo) * (np.float32(AXIS_CELLS) / (hi - lo))).astype(np.int64), AXIS_CELLS - 1)
        for b in range(10):
            code |= ((cells >> b) & 1) << (3 * b + 2 - a)
    return code.astype(np.uint32)


@numba.njit(cache=False)
def _clz(x):
    if x == 0:
        return 32
    k = 0
    while (x & np.uint32(0x80000000)) == 0:
        x = np.uint32(x << np.uint32(1))
        k += 1
    return k


@numba.njit(cache=False)
def _delta(keys, n, i, j):
    if j < 0 or j >= n:
        return -1
    a = keys[i]
    b = keys[j]
    if a != b:
        return _clz(np.uint32(a ^ b))
    return 32 + _clz(np.uint32(i ^ j))


@numba.njit(cache=False)
def hierarchy(keys, links, up, leaf_up, span):
    """cuda_build._hierarchy, a loop over the rows."""
    n = keys.shape[0]
    for i in range(n - 1):
        d = 1 if _delta(keys, n, i, i + 1) > _delta(keys, n, i, i - 1) else -1
        least = _delta(keys, n, i, i - d)
        most = 2
        while _delta(keys, n, i, i + most * d) > least:
            most *= 2
        length = 0
        step = most // 2
        while step >= 1:
            if _delta(keys, n, i, i + (length + step) * d) > least:
                length += step
            step //= 2
        j = i + length * d
        node = _delta(keys, n, i, j)
        split = 0
        step = length
        while True:
            step = (step + 1) // 2
            if _delta(keys, n, i, i + (split + step) * d) > node:
                split += step
            if step <= 1:
                break
        gamma = i + split * d + min(d, 0)
        first = min(i, j)
        last = max(i, j)
        span[i, 0] = first
        span[i, 1] = last - first + 1
        for slot in range(2):
            child = gamma + slot
            if (slot == 0 and first == gamma) or (slot == 1 and last == gamma + 1):
                links[i, REF + slot] = child
                links[i, COUNT + slot] = 1
                leaf_up[child] = 2 * i + slot
            else:
                links[i, REF + slot] = child
                links[i, COUNT + slot] = INNER
                up[child] = 2 * i + slot
    up[0] = -1


@numba.njit(cache=False)
def _half_area(lx, ly, lz, hx, hy, hz):
    zero = np.float32(0)
    dx, dy, dz = max(hx - lx, zero), max(hy - ly, zero), max(hz - lz, zero)
    return dx * dy + dy * dz + dz * dx


TREELET = cuda_build.TREELET
SUBSETS = cuda_build.SUBSETS
TREELET_GAIN = cuda_build._GAIN
INF = np.float32(np.inf)


@numba.njit(cache=False)
def _entry(nodes, links, span, kid, below, costs, row, slot, e, tb, tn, tc, th, tw, tref, tcnt, trow):
    """Piece e of a treelet: child slot of row (its box, link, row below,
    cost, height, rows below, spheres), read by atomics that add nothing:
    other threads wrote them, and a plain load could find a stale line in
    this SM's L1."""
    link = 2 * row + slot
    for q in range(6):
        tb[e, q] = nodes[row, 6 * slot + q]
    tref[e] = links[row, REF + slot]
    tcnt[e] = links[row, COUNT + slot]
    trow[e] = kid[link]
    tc[e] = costs[link]
    th[e] = below[2 * link]
    tw[e] = below[2 * link + 1]
    tn[e] = span[trow[e], 1] if trow[e] >= 0 else 1


@numba.njit(cache=False)
def _union(tb, part, size):
    """The box of the pieces in the bit set part."""
    lx = ly = lz = INF
    hx = hy = hz = -INF
    for e in range(size):
        if part & (1 << e):
            lx, ly, lz = min(lx, tb[e, 0]), min(ly, tb[e, 1]), min(lz, tb[e, 2])
            hx, hy, hz = max(hx, tb[e, 3]), max(hy, tb[e, 4]), max(hz, tb[e, 5])
    return lx, ly, lz, hx, hy, hz


@numba.njit(cache=False)
def _piece(part):
    """The piece of a set of one."""
    e = 0
    while (1 << e) != part:
        e += 1
    return e


@numba.njit(cache=False)
def _treelet(x, old, nodes, links, span, up, leaf_up, kid, below, costs, leaf_max):
    """cuda_build._treelet. Row x's subtree (its rows' boxes, links and costs final) made the
    cheapest tree over its treelet (Karras and Aila 2013): x's two
    children, then, up to TREELET pieces, the piece of largest area that is
    a row (not a leaf) replaced by its two children. The cheapest binary
    tree over the pieces, in any order, by a programme over their subsets
    (bit sets, each after its own subsets in numeric order: its box's half
    area, spheres, cost, best split into two, whether a leaf, and as a child
    its height and the rows a walk reaches below it); a set of spheres is
    cut into a leaf as _bounds_up cuts. The rows the treelet frees (x's and
    the replaced ones) hold the new tree: links, boxes, counts, costs and
    links up written here. A leaf's spheres are now no range of the sort's
    order: _reorder puts them in tree order and sets the leaves' refs.
    x is changed only where the cost falls below TREELET_GAIN times old (x's cost
    as it is), so that rounding never churns equal trees. Returns (cost,
    height, rows) of x after, or (old, -1, -1) where nothing changed."""
    K = TREELET
    tb = np.empty((TREELET, 6), np.float32)
    tn = np.empty(TREELET, np.int32)
    tc = np.empty(TREELET, np.float32)
    th = np.empty(TREELET, np.int32)
    tw = np.empty(TREELET, np.int32)
    tref = np.empty(TREELET, np.int32)
    tcnt = np.empty(TREELET, np.int32)
    trow = np.empty(TREELET, np.int32)
    rows = np.empty(TREELET, np.int32)
    area = np.empty(SUBSETS, np.float32)
    cnt = np.empty(SUBSETS, np.int32)
    cost = np.empty(SUBSETS, np.float32)
    split = np.empty(SUBSETS, np.int32)
    hh = np.empty(SUBSETS, np.int32)
    ww = np.empty(SUBSETS, np.int32)
    leaf = np.empty(SUBSETS, np.int8)
    stack = np.empty((TREELET, 2), np.int32)
    rows[0] = x
    used = 1
    _entry(nodes, links, span, kid, below, costs, x, 0, 0, tb, tn, tc, th, tw, tref, tcnt, trow)
    _entry(nodes, links, span, kid, below, costs, x, 1, 1, tb, tn, tc, th, tw, tref, tcnt, trow)
    size = 2
    while size < K:
        best = -1
        best_area = np.float32(-1)
        for e in range(size):
            if tcnt[e] == INNER:
                ar = _half_area(tb[e, 0], tb[e, 1], tb[e, 2], tb[e, 3], tb[e, 4], tb[e, 5])
                if ar > best_area:
                    best_area = ar
                    best = e
        if best < 0:
            break
        r = tref[best]
        rows[used] = r
        used += 1
        _entry(nodes, links, span, kid, below, costs, r, 0, best, tb, tn, tc, th, tw, tref, tcnt, trow)
        _entry(nodes, links, span, kid, below, costs, r, 1, size, tb, tn, tc, th, tw, tref, tcnt, trow)
        size += 1
    if size < 3:
        return old, -1, -1
    full = (1 << size) - 1
    for sm in range(1, full + 1):
        low = sm & -sm
        if sm == low:
            e = _piece(sm)
            cnt[sm] = tn[e]
            cost[sm] = tc[e]
            hh[sm] = th[e]
            ww[sm] = tw[e]
            continue
        lx, ly, lz, hx, hy, hz = _union(tb, sm, size)
        area[sm] = _half_area(lx, ly, lz, hx, hy, hz)
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
    if not cost[full] < old * TREELET_GAIN:
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
                e = _piece(part)
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
            lx, ly, lz, hx, hy, hz = _union(tb, part, size)
            nodes[row, col] = lx
            nodes[row, col + 1] = ly
            nodes[row, col + 2] = lz
            nodes[row, col + 3] = hx
            nodes[row, col + 4] = hy
            nodes[row, col + 5] = hz
            span[child, 0] = -1  # no range of the sort's order
            span[child, 1] = cnt[part]
            kid[link] = child
            up[child] = link
            costs[link] = cost[part]
            below[2 * link] = hh[part]
            below[2 * link + 1] = ww[part]
            if leaf[part] != 0:
                links[row, REF + slot] = -1  # set by _reorder
                links[row, COUNT + slot] = cnt[part]
            else:
                links[row, REF + slot] = child
                links[row, COUNT + slot] = INNER
            stack[top, 0] = part
            stack[top, 1] = child
            top += 1
    return cost[full], hh[full], ww[full]


@numba.njit(cache=False)
def reorder(spheres, n, order, leaf_up, up, links, kid, span, order_out, leaf_up_out, ordered):
    """After treelets, the spheres in the tree's order, so that every leaf
    is again a range of them: leaf k's place is the spheres left of it in
    the tree (on its way up, the left sibling's count wherever it is a right
    child). Its sphere, its index and its link up go there; on the way up
    while it is the leftmost sphere of the child it climbs from, it sets
    that child's ref where the child is a leaf (every leaf has one leftmost
    sphere)."""
    for k in range(n):
        _reorder_one(spheres, k, order, leaf_up, up, links, kid, span, order_out, leaf_up_out, ordered)


@numba.njit(cache=False)
def _reorder_one(spheres, k, order, leaf_up, up, links, kid, span, order_out, leaf_up_out, ordered):
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
    for a in range(4):
        ordered[a, rank] = spheres[a, s]
    link = leaf_up[k]
    while link >= 0:
        row = link // 2
        slot = link - 2 * row
        if links[row, COUNT + slot] != INNER:
            links[row, REF + slot] = rank
        if slot == 1:
            return
        link = up[row]


@numba.njit(cache=False)
def bounds_up(ordered, leaf_up, up, span, nodes, links, kid, leaf_max, sah, restructure):
    """cuda_build._bounds_up, each row done once both its children are: the
    leaves in order, each climbing while it arrives second (as on the GPU,
    where the order of arrivals changes no value: min, max and a sum of two
    are commutative). Returns (depth, rows reached, SAH cost)."""
    n = ordered.shape[1]
    m = nodes.shape[0]
    arrived = np.zeros(m, np.int32)
    below = np.zeros(4 * m, np.int32)
    costs = np.zeros(2 * m, np.float32)
    h = w = 0
    c = a = np.float32(0)
    for k in range(n):
        cx, cy, cz, r = ordered[0, k], ordered[1, k], ordered[2, k], ordered[3, k]
        pr = r + (r + (abs(cx) + abs(cy) + abs(cz))) * PAD
        lx, ly, lz, hx, hy, hz = cx - pr, cy - pr, cz - pr, cx + pr, cy + pr, cz + pr
        h = 0
        w = 0
        c = _half_area(lx, ly, lz, hx, hy, hz)
        a = c
        cur = -1
        link = leaf_up[k]
        while link >= 0:
            row = link // 2
            slot = link - 2 * row
            col = slot * 6
            nodes[row, col] = lx
            nodes[row, col + 1] = ly
            nodes[row, col + 2] = lz
            nodes[row, col + 3] = hx
            nodes[row, col + 4] = hy
            nodes[row, col + 5] = hz
            below[2 * link] = h
            below[2 * link + 1] = w
            costs[link] = c
            kid[link] = cur
            arrived[row] += 1
            if arrived[row] == 1:
                break
            other = (1 - slot) * 6
            sib = 2 * row + 1 - slot
            lx = min(lx, nodes[row, other])
            ly = min(ly, nodes[row, other + 1])
            lz = min(lz, nodes[row, other + 2])
            hx = max(hx, nodes[row, other + 3])
            hy = max(hy, nodes[row, other + 4])
            hz = max(hz, nodes[row, other + 5])
            h = 1 + max(h, below[2 * sib])
            w = 1 + w + below[2 * sib + 1]
            a = _half_area(lx, ly, lz, hx, hy, hz)
            c = NODE_COST * a + (c + costs[sib])
            cur = row
            if restructure != 0 and leaf_max > 0 and span[row, 1] > 2:
                c2, h2, w2 = _treelet(row, c, nodes, links, span, up, leaf_up, kid, below, costs, leaf_max)
                if h2 >= 0:
                    c, h, w = c2, h2, w2
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
    return h, w, (c / a if a > 0 else np.float32(0))


def build(spheres: np.ndarray, quality: str = "sah", leaf_size: int | None = None):
    """The GPU's tree of the (>= 4, n) spheres (n >= 2): (nodes, order,
    ordered, depth, rows reached, its SAH cost as the device sums it)."""
    n = spheres.shape[1]
    leaf_max = leaf_size if leaf_size is not None else (cuda_build.LEAF_SIZE if quality == "lbvh" else bvh.LEAF_MAX)
    restructure = int(quality == "treelet")
    order = np.argsort(morton(spheres), kind="stable").astype(np.int32)
    keys = morton(spheres)[order]
    m = n - 1
    nodes = np.zeros((m, layout.NODE_FLOATS), np.float32)
    links = nodes.view(np.int32)
    up = np.zeros(m, np.int64)
    leaf_up = np.zeros(n, np.int64)
    span = np.zeros((m, 2), np.int32)
    hierarchy(keys, links, up, leaf_up, span)
    ordered = np.ascontiguousarray(spheres[:4, order])
    sah = int(quality != "lbvh")
    kid = np.zeros(2 * m, np.int32)
    depth, rows, cost = bounds_up(ordered, leaf_up, up, span, nodes, links, kid, leaf_max, sah, restructure)
    for _ in range(cuda_build.TREELET_PASSES - 1 if restructure else 0):
        depth, rows, cost = bounds_up(ordered, leaf_up, up, span, nodes, links, kid, leaf_max, sah, restructure)
    if restructure:
        tree_order = np.empty_like(order)
        tree_up = np.empty_like(leaf_up)
        ordered = np.empty_like(ordered)
        reorder(spheres, n, order, leaf_up, up, links, kid, span, tree_order, tree_up, ordered)
        order = tree_order
    return nodes, order, ordered, int(depth), int(rows), float(cost)


def main() -> int:
    import raybench

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--spheres", action="append", type=int, help="default: 1000, 100000, 1000000")
    parser.add_argument("--quality", action="append", choices=cuda_build.QUALITIES, help="default: all")
    args = parser.parse_args()
    for n in args.spheres or [1000, 100_000, 1_000_000]:
        spheres = raybench.random_spheres(n, seed=0).spheres
        host = bvh.build(spheres)
        host_sah = tree_cost.sah_cost(host.nodes)
        for quality in args.quality or ["lbvh", "sah", "treelet"]:  # as cuda_build.QUALITIES, cheapest first
            start = time.perf_counter()
            nodes, _order, _ordered, depth, rows, cost = build(spheres, quality)
            seconds = time.perf_counter() - start
            sah = tree_cost.sah_cost(nodes)
            row = {
                "spheres": n,
                "quality": quality,
                "sah": round(sah, 3),
                "sah_device_sum": round(cost, 3),
                "host_sah": round(host_sah, 3),
                "sah_over_host": round(sah / host_sah, 4),
                "depth": depth,
                "host_depth": host.depth,
                "rows_reached": rows,
                "host_rows": host.node_count,
                "model_s": round(seconds, 2),
            }
            print(json.dumps(row), flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
