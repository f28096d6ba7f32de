"""A CPU model of the tree that backends/cuda/build.py builds on the GPU: the
same Morton codes, the same stable order, Karras's hierarchy, the same
bottom-up pass (boxes, SAH costs, the leaves it cuts, the treelets it
rebuilds) and reorder, in the same float32 arithmetic. The hierarchy's rows,
the treelet step and the reorder are the GPU's own functions
(bvh/lbvh_steps.py) compiled by numba.njit; the bottom-up pass is a loop
over the leaves in order where the GPU has a thread a leaf. Under numba's
CUDA simulator it gives the kernels' tree bit for bit (tests/test_cuda_build.py
checks it), as it gives the WGSL port's, backends/wgpu/build.py's, on
lavapipe (tests/test_wgpu_build.py); benchmarks/gpu_tree_model.py uses it for
the SAH cost of the GPU's trees at sizes the simulator cannot build (100,000
and 1,000,000 spheres) on a machine with no GPU. A GPU may fuse
multiply-adds where the model does not, which can tip a leaf's choice where
two costs tie to the last bit; the cost is the same to a few float32
epsilons.
"""

from __future__ import annotations

import numba
import numpy as np

from .. import layout
from . import lbvh, lbvh_steps
from .sah import LEAF_MAX, NODE_COST

AXIS_CELLS = lbvh.AXIS_CELLS
PAD = layout.PAD
INNER = layout.INNER
REF = layout.REF
COUNT = layout.COUNT
QUALITIES = ("sah", "treelet", "lbvh")  # backends/cuda/build.py's


@numba.njit(cache=False)
def _load(a, i):
    return a[i]


_jit = numba.njit(cache=False)
_steps = lbvh_steps.build(_jit, lbvh_steps.cpu_target(_jit), _load, _load)
_hierarchy_row = _steps.hierarchy_row
_half_area = _steps.half_area
_treelet = _steps.treelet
_reorder_one = _steps.reorder_one


def morton(spheres: np.ndarray) -> np.ndarray:
    """Each centre's 30-bit Morton code in the centres' box (backends/cuda/build.py's _morton arithmetic)."""
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
def hierarchy(keys, links, up, leaf_up, span):
    """backends/cuda/build.py's _hierarchy, a loop over the rows."""
    n = keys.shape[0]
    for i in range(n - 1):
        _hierarchy_row(keys, n, i, links, up, leaf_up, span)


@numba.njit(cache=False)
def reorder(spheres, n, order, leaf_up, up, links, kid, span, order_out, leaf_up_out, ordered):
    """backends/cuda/build.py's _reorder, a loop over the spheres."""
    for k in range(n):
        _reorder_one(spheres, k, order, leaf_up, up, links, kid, span, order_out, leaf_up_out, ordered)


@numba.njit(cache=False)
def bounds_up(ordered, leaf_up, up, span, nodes, links, kid, leaf_max, sah, restructure):
    """backends/cuda/build.py's _bounds_up, each row done once both its children are: the
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


def build(spheres: np.ndarray, quality: str = "sah", leaf_size: int | None = None, passes: int | None = None):
    """The GPU's tree of the (>= 4, n) spheres (n >= 2): (nodes, order,
    ordered, depth, rows reached, its SAH cost as the device sums it).
    passes: the bottom-up passes of treelets (default lbvh_steps.TREELET_PASSES)."""
    n = spheres.shape[1]
    leaf_max = leaf_size if leaf_size is not None else (lbvh.LEAF_SIZE if quality == "lbvh" else LEAF_MAX)
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
    for _ in range((passes or lbvh_steps.TREELET_PASSES) - 1 if restructure else 0):
        depth, rows, cost = bounds_up(ordered, leaf_up, up, span, nodes, links, kid, leaf_max, sah, restructure)
    if restructure:
        tree_order = np.empty_like(order)
        tree_up = np.empty_like(leaf_up)
        ordered = np.empty_like(ordered)
        reorder(spheres, n, order, leaf_up, up, links, kid, span, tree_order, tree_up, ordered)
        order = tree_order
    return nodes, order, ordered, int(depth), int(rows), float(cost)
