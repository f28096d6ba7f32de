"""A CPU model of the tree that backends/cuda/build.py builds on the GPU: the
same Morton codes, the same stable order, Karras's hierarchy, the same
bottom-up pass (boxes, SAH costs, the leaves it cuts, the treelets it
rebuilds) and reorder, in the same float32 arithmetic: the GPU's own steps
(bvh/lbvh_steps.py: a hierarchy row, a leaf's climb, the treelet step, a
sphere's reorder) compiled by numba.njit, each a loop over the rows, leaves
or spheres where the GPU has a thread each (the leaves in order: each row is
done once both its children are, and the last leaf reaches the root). Under numba's
CUDA simulator it gives the kernels' tree bit for bit (tests/test_cuda_build.py
checks it), as it gives the WGSL port's, backends/wgpu/build.py's, on
lavapipe (tests/test_wgpu_build.py); benchmarks/archive/gpu_tree_model.py uses it for
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
from ..kernels.primitives import sphere
from . import lbvh, lbvh_steps
from .sah_steps import LEAF_MAX

AXIS_CELLS = lbvh.AXIS_CELLS
QUALITIES = lbvh.QUALITIES


@numba.njit(cache=False)
def _load(a, i):
    return a[i]


_jit = numba.njit(cache=False)
_steps = lbvh_steps.make(_jit, lbvh_steps.cpu_target(_jit), _load, _load, _jit(lbvh_steps.cpu_arrive), sphere)
_hierarchy_row = _steps.hierarchy_row
_reorder_one = _steps.reorder_one
_climb = _steps.climb


def morton(spheres: np.ndarray) -> np.ndarray:
    """Each centre's 30-bit Morton code in the centres' box (backends/cuda/build.py's _morton arithmetic)."""
    centres = sphere.centres(spheres)
    n = centres.shape[1]
    code = np.zeros(n, np.int64)
    for a in range(3):
        c = centres[a]
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
def bounds_up(spheres, order, leaf_up, up, span, nodes, links, kid, ordered, leaf_max, sah, restructure):
    """backends/cuda/build.py's _bounds_up, each row done once both its children are: the
    leaves in order, each climbing while it arrives second (as on the GPU,
    where the order of arrivals changes no value: min, max and a sum of two
    are commutative); the last leaf reaches the root. Returns (depth, rows reached, SAH cost)."""
    n = order.shape[0]
    m = nodes.shape[0]
    arrived = np.zeros(m, np.int32)
    below = np.zeros(4 * m, np.int32)
    costs = np.zeros(2 * m, np.float32)
    stats = np.zeros(2, np.int32)
    cost = np.zeros(1, np.float32)
    for k in range(n):
        _climb(
            spheres, k, order, leaf_up, up, span, nodes, links, below, costs, kid, arrived, ordered, stats, cost,
            leaf_max, sah, restructure,
        )  # fmt: skip
    return stats[0], stats[1], cost[0]


def build(spheres: np.ndarray, quality: str = "sah", leaf_size: int | None = None, passes: int | None = None):
    """The GPU's tree of the (>= 4, n) spheres (n >= 2): (nodes, order,
    ordered, depth, rows reached, its SAH cost as the device sums it).
    passes: the bottom-up passes of treelets (default lbvh.TREELET_PASSES)."""
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
    ordered = np.empty((sphere.LEAF_ROWS, n), np.float32)
    sah = int(quality != "lbvh")
    kid = np.zeros(2 * m, np.int32)
    args = (spheres, order, leaf_up, up, span, nodes, links, kid, ordered, leaf_max, sah, restructure)
    depth, rows, cost = bounds_up(*args)
    for _ in range((passes or lbvh.TREELET_PASSES) - 1 if restructure else 0):
        depth, rows, cost = bounds_up(*args)
    if restructure:
        tree_order = np.empty_like(order)
        tree_up = np.empty_like(leaf_up)
        ordered = np.empty_like(ordered)
        reorder(spheres, n, order, leaf_up, up, links, kid, span, tree_order, tree_up, ordered)
        order = tree_order
    return nodes, order, ordered, int(depth), int(rows), float(cost)
