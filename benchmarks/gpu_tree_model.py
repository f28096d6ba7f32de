"""A CPU model of the tree that backends/cuda_build.py builds on the GPU: the
same Morton codes, the same stable order, Karras's hierarchy and the same
bottom-up pass (boxes, SAH costs, the leaves it cuts) in the same float32
arithmetic, written with NumPy and Numba's CPU compiler. Under numba's CUDA
simulator it gives the kernels' tree bit for bit (tests/test_cuda_build.py
checks it); here it gives the SAH cost of the GPU's trees at sizes the
simulator cannot build (100,000 and 1,000,000 spheres) on a machine with no
GPU. A GPU may fuse multiply-adds where the model does not, which can tip
a leaf's choice where two costs tie to the last bit; the cost is the same to
a few float32 epsilons.

    python benchmarks/gpu_tree_model.py [--spheres 1000 --spheres 100000] [--quality sah --quality lbvh]

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

from raybench import bvh, layout, tree_cost
from raybench.backends import cuda_build

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
        span[i, 1] = last
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
TREELET_GAIN = cuda_build._GAIN
INF = np.float32(np.inf)


@numba.njit(cache=False)
def _entry(nodes, links, span, kid, below, costs, row, slot, e, tb, tn, tf, tc, th, tw, tref, tcnt, trow):
    """Entry e of the treelet: child slot of row, as cuda_build._entry reads it."""
    link = 2 * row + slot
    for q in range(6):
        tb[e, q] = nodes[row, 6 * slot + q]
    tref[e] = links[row, REF + slot]
    tcnt[e] = links[row, COUNT + slot]
    trow[e] = kid[link]
    tc[e] = costs[link]
    th[e] = below[2 * link]
    tw[e] = below[2 * link + 1]
    if tcnt[e] == INNER:
        tf[e] = span[tref[e], 0]
        tn[e] = span[tref[e], 1] - span[tref[e], 0] + 1
    else:
        tf[e] = tref[e]
        tn[e] = tcnt[e]


@numba.njit(cache=False)
def treelet(x, old, nodes, links, span, up, leaf_up, kid, below, costs, leaf_max):
    """cuda_build._treelet: row x's subtree, its rows' boxes, links and costs
    final, restructured to the cheapest tree over the same ordered pieces;
    returns (cost, height, rows) of x after, old its cost before."""
    K = TREELET
    tb = np.empty((K, 6), np.float32)
    tn = np.empty(K, np.int64)
    tf = np.empty(K, np.int64)
    tc = np.empty(K, np.float32)
    th = np.empty(K, np.int64)
    tw = np.empty(K, np.int64)
    tref = np.empty(K, np.int64)
    tcnt = np.empty(K, np.int64)
    trow = np.empty(K, np.int64)
    rows = np.empty(K, np.int64)
    rows[0] = x
    used = 1
    _entry(nodes, links, span, kid, below, costs, x, 0, 0, tb, tn, tf, tc, th, tw, tref, tcnt, trow)
    _entry(nodes, links, span, kid, below, costs, x, 1, 1, tb, tn, tf, tc, th, tw, tref, tcnt, trow)
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
        for e in range(size - 1, best, -1):
            for q in range(6):
                tb[e + 1, q] = tb[e, q]
            tn[e + 1] = tn[e]
            tf[e + 1] = tf[e]
            tc[e + 1] = tc[e]
            th[e + 1] = th[e]
            tw[e + 1] = tw[e]
            tref[e + 1] = tref[e]
            tcnt[e + 1] = tcnt[e]
            trow[e + 1] = trow[e]
        _entry(nodes, links, span, kid, below, costs, r, 0, best, tb, tn, tf, tc, th, tw, tref, tcnt, trow)
        _entry(nodes, links, span, kid, below, costs, r, 1, best + 1, tb, tn, tf, tc, th, tw, tref, tcnt, trow)
        size += 1
    if size < 3:
        return old, -1, -1
    # the cheapest tree over the ordered pieces: interval [i, j] at i * K + j
    area = np.empty(K * K, np.float32)
    cnt = np.empty(K * K, np.int64)
    cost = np.empty(K * K, np.float32)
    split = np.empty(K * K, np.int64)
    leaf = np.empty(K * K, np.int64)
    hh = np.empty(K * K, np.int64)
    ww = np.empty(K * K, np.int64)
    for i in range(size):
        lx, ly, lz, hx, hy, hz = tb[i, 0], tb[i, 1], tb[i, 2], tb[i, 3], tb[i, 4], tb[i, 5]
        cost[i * K + i] = tc[i]
        cnt[i * K + i] = tn[i]
        hh[i * K + i] = th[i]
        ww[i * K + i] = tw[i]
        leaf[i * K + i] = 1 if tcnt[i] != INNER else 0
        for j in range(i + 1, size):
            lx, ly, lz = min(lx, tb[j, 0]), min(ly, tb[j, 1]), min(lz, tb[j, 2])
            hx, hy, hz = max(hx, tb[j, 3]), max(hy, tb[j, 4]), max(hz, tb[j, 5])
            area[i * K + j] = _half_area(lx, ly, lz, hx, hy, hz)
            cnt[i * K + j] = cnt[i * K + j - 1] + tn[j]
    for length in range(2, size + 1):
        for i in range(size - length + 1):
            j = i + length - 1
            best = INF
            at = i
            for s in range(i, j):
                v = cost[i * K + s] + cost[(s + 1) * K + j]
                if v < best:
                    best = v
                    at = s
            ij = i * K + j
            inner = NODE_COST * area[ij] + best
            split[ij] = at
            lc = np.float32(cnt[ij]) * area[ij]
            hl = 0 if leaf[i * K + at] != 0 else hh[i * K + at]
            hr = 0 if leaf[(at + 1) * K + j] != 0 else hh[(at + 1) * K + j]
            wl = 0 if leaf[i * K + at] != 0 else ww[i * K + at]
            wr = 0 if leaf[(at + 1) * K + j] != 0 else ww[(at + 1) * K + j]
            hh[ij] = 1 + max(hl, hr)
            ww[ij] = 1 + wl + wr
            if length < size and cnt[ij] <= leaf_max and lc <= inner:
                cost[ij] = lc
                leaf[ij] = 1
            else:
                cost[ij] = inner
                leaf[ij] = 0
    whole = size - 1
    if not cost[whole] < old * TREELET_GAIN:
        return old, -1, -1
    # the new rows, from the root down: interval, row (a stack of at most K)
    stack = np.empty((K, 3), np.int64)
    stack[0, 0], stack[0, 1], stack[0, 2] = 0, whole, x
    top = 1
    used = 1
    while top > 0:
        top -= 1
        i, j, row = stack[top, 0], stack[top, 1], stack[top, 2]
        at = split[i * K + j]
        for slot in range(2):
            a = i if slot == 0 else at + 1
            b = at if slot == 0 else j
            link = 2 * row + slot
            col = 6 * slot
            if a == b:
                for q in range(6):
                    nodes[row, col + q] = tb[a, q]
                links[row, REF + slot] = tref[a]
                links[row, COUNT + slot] = tcnt[a]
                kid[link] = trow[a]
                costs[link] = tc[a]
                below[2 * link] = th[a]
                below[2 * link + 1] = tw[a]
                if trow[a] >= 0:
                    up[trow[a]] = link
                else:
                    leaf_up[tref[a]] = link
                continue
            child = rows[used]
            used += 1
            lx, ly, lz, hx, hy, hz = tb[a, 0], tb[a, 1], tb[a, 2], tb[a, 3], tb[a, 4], tb[a, 5]
            for e in range(a + 1, b + 1):
                lx, ly, lz = min(lx, tb[e, 0]), min(ly, tb[e, 1]), min(lz, tb[e, 2])
                hx, hy, hz = max(hx, tb[e, 3]), max(hy, tb[e, 4]), max(hz, tb[e, 5])
            nodes[row, col], nodes[row, col + 1], nodes[row, col + 2] = lx, ly, lz
            nodes[row, col + 3], nodes[row, col + 4], nodes[row, col + 5] = hx, hy, hz
            span[child, 0] = tf[a]
            span[child, 1] = tf[b] + tn[b] - 1
            kid[link] = child
            up[child] = link
            ab = a * K + b
            costs[link] = cost[ab]
            if leaf[ab] != 0:
                links[row, REF + slot] = tf[a]
                links[row, COUNT + slot] = cnt[ab]
                below[2 * link] = 0
                below[2 * link + 1] = 0
            else:
                links[row, REF + slot] = child
                links[row, COUNT + slot] = INNER
                below[2 * link] = hh[ab]
                below[2 * link + 1] = ww[ab]
            stack[top, 0], stack[top, 1], stack[top, 2] = a, b, child
            top += 1
    return cost[whole], hh[whole], ww[whole]


@numba.njit(cache=False)
def bounds_up(ordered, leaf_up, up, span, nodes, links, leaf_max, sah, restructure):
    """cuda_build._bounds_up, each row done once both its children are: the
    leaves in order, each climbing while it arrives second (as on the GPU,
    where the order of arrivals changes no value: min, max and a sum of two
    are commutative). Returns (depth, rows reached, SAH cost)."""
    n = ordered.shape[1]
    m = nodes.shape[0]
    arrived = np.zeros(m, np.int32)
    below = np.zeros(4 * m, np.int32)
    costs = np.zeros(2 * m, np.float32)
    kid = np.zeros(2 * m, np.int64)
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
            if restructure != 0 and leaf_max > 0:
                c2, h2, w2 = treelet(row, c, nodes, links, span, up, leaf_up, kid, below, costs, leaf_max)
                if h2 >= 0:
                    c, h, w = c2, h2, w2
            link = up[row]
            if link >= 0:
                parent = link // 2
                pslot = link - 2 * parent
                count = span[row, 1] - span[row, 0] + 1
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
    depth, rows, cost = bounds_up(ordered, leaf_up, up, span, nodes, links, leaf_max, sah, restructure)
    return nodes, order, ordered, int(depth), int(rows), float(cost)


def main() -> int:
    import raybench

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--spheres", action="append", type=int, help="default: 1000, 100000, 1000000")
    parser.add_argument("--quality", action="append", help="default: lbvh and sah")
    args = parser.parse_args()
    for n in args.spheres or [1000, 100_000, 1_000_000]:
        spheres = raybench.random_spheres(n, seed=0).spheres
        host = bvh.build(spheres)
        host_sah = tree_cost.sah_cost(host.nodes)
        for quality in args.quality or ["lbvh", "sah", "treelet"]:
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
