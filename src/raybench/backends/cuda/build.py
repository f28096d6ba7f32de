"""The BVH built on the GPU (numba-cuda): an LBVH (Karras 2012, "Maximizing
parallelism in the construction of BVHs, octrees, and k-d trees") written in
raybench.bvh's node layout, so every walk reads it unchanged.

Steps, a kernel each (the bounds two, the sort three a pass), all on the device; the host
waits once, at the end, to read the tree's depth:
  1. bounds   the box of the spheres' centres (a box per block, then one
              block unites them);
  2. morton   each centre's 30-bit Morton code in that box, beside its index;
  3. sort     (code, index) pairs by code: an LSD radix sort of DIGIT_BITS a
              pass, each pass count (a histogram per block), scan (where each
              block's keys of each digit go) and scatter. numba-cuda has no
              sort; the scatter is stable, so equal codes keep the order of
              their indices: the tie-break Karras's hierarchy needs;
  4. hierarchy Karras's internal nodes from the sorted codes, internal node i
              in row i (the root is row 0), each child a row (INNER) or, where
              it is one sphere, a leaf of it. Equal codes are told apart by
              their places, as Karras does: a key of code bits then place
              bits, all distinct;
  5. bounds up one thread per leaf climbs to the root; at each row the first of
              its two children to arrive stops, the second (an atomic counter
              says which) unites both boxes and goes on. On its way it cuts
              the leaves: a row of few enough spheres becomes a leaf of them
              (ref: the first one's place in leaf order) where the SAH says
              (QUALITY). The same pass writes the ordered spheres (the
              scene's very float32 values, as the host builder does), each
              row's height and SAH cost.
Refit (spheres moved, same tree) is step 5 alone, its leaves kept: the tree's
shape is kept, its boxes are the moved spheres'.

The walks' stack holds layout.STACK entries, so a tree must be at most
MAX_DEPTH rows deep. A radix tree's depth is at most its keys' bits: 30 code
bits and ceil(log2 n) place bits, so under 2**18 spheres no tree is too deep;
above, unlucky inputs could be (spheres at positions halving towards a point,
then many at one code). The depth, read at the end, tells; a tree too deep is
replaced by the host's build (raybench.bvh), whose depth is bounded.

Under two spheres there is no internal node to build: the host's tree (one
row) is uploaded.
"""

from __future__ import annotations

import functools
import math
import time
from dataclasses import dataclass
from types import SimpleNamespace

import numpy as np
from numba import config, cuda

from ... import bvh as bvh_mod
from ... import compiled
from ...bvh import lbvh, lbvh_steps
from ...bvh.lbvh import AXIS_CELLS, CODE_BITS, LEAF_SIZE
from ...kernels.primitives import sphere
from ...layout import MAX_DEPTH, NODE_FLOATS
from .launch import Launches

# The radix sort: DIGIT_BITS a pass (5 passes for 30 bits); a block of
# SORT_THREADS threads sorts a tile of SORT_THREADS * ITEMS keys, each thread
# ITEMS consecutive ones, so its counts per digit (RADIX x SORT_THREADS, 32
# KiB of shared memory) make the scatter stable without warp intrinsics
# (which the simulator lacks).
DIGIT_BITS = 6
RADIX = 1 << DIGIT_BITS
DIGIT_MASK = RADIX - 1
PASSES = -(-CODE_BITS // DIGIT_BITS)
# Under numba's simulator every thread is a Python thread: there the blocks
# are small (the same kernels, their sizes only), which also gives the tests'
# scenes of tens of spheres several tiles to sort.
_SIM = bool(config.ENABLE_CUDASIM)
SORT_THREADS = 8 if _SIM else 128
ITEMS = 4 if _SIM else 8
SORT_TILE = SORT_THREADS * ITEMS
SORT_CELLS = RADIX * SORT_THREADS
# The one-block kernels (the centres' bounds merged, the scan of the
# histograms): a block as large as CUDA has, so that each thread's run of
# entries is short.
ONE_BLOCK = 32 if _SIM else 1024
# The centres' bounds: at most BOUNDS_BLOCKS blocks of THREADS, each a part.
BOUNDS_BLOCKS = 4 * ONE_BLOCK
# The other kernels: a thread an element, in blocks of THREADS.
THREADS = 32 if _SIM else 256
# Where leaves are cut. Every LBVH subtree covers consecutive spheres of the
# leaf order, so any subtree can be stored as one leaf of them all.
#   "lbvh": every subtree of at most LEAF_SIZE spheres is a leaf (the first
#           GPU tree; the leaf-size sweep found 2 and 4 alike:
#           docs/notes/gpu-build.md#measured-on-the-h200).
#   "sah":  a subtree of at most bvh.LEAF_MAX spheres is a leaf where its
#           SAH cost as a leaf is no more than as a row with the best cut
#           below it (the host's builder weighs the same, greedily), decided
#           bottom-up in the pass that fits the boxes, at no extra launch.
#   "treelet": "sah", and each row's subtree first made the cheapest tree
#           over its treelet of TREELET pieces (lbvh_steps' treelet, Karras and Aila
#           2013, one pass bottom-up), then the spheres put in the new tree's
#           order (_reorder, one launch more).
QUALITIES, QUALITY = lbvh.QUALITIES, lbvh.QUALITY
# A treelet's pieces and the gain that rebuilds one: bvh/lbvh_steps.py,
# where the treelet step is written once.
TREELET = lbvh_steps.TREELET
SUBSETS = lbvh_steps.SUBSETS
# Device bytes a Builder holds per sphere: keys and values twice (the sort's
# two buffers), the links up (8 + 8), the rows' spans (8), what lies below
# each child (heights and rows 16, costs 8, rows 8), the counters (4), the
# node rows (64) and the ordered spheres (16); the histograms add under 1;
# treelets add the leaves' links up in the tree's order (8).
DEVICE_SPHERE_BYTES = 16 + 16 + 48 + 4 + NODE_FLOATS * 4 + 16 + 1


def _blocks(n: int, per: int) -> int:
    return max(1, math.ceil(n / per))


@cuda.jit(device=True)
def _empty_box(lo, hi, t):
    """Thread t's box in the block's shared lo, hi: empty, so that the
    first point it takes in is its box."""
    for a in range(3):
        lo[a, t] = np.float32(np.inf)
        hi[a, t] = np.float32(-np.inf)


@cuda.jit(device=True)
def _reduce_box(lo, hi, t, size):
    """The block's boxes lo[:, 0:size], hi[:, 0:size] (shared) united into
    lo[:, 0], hi[:, 0] by a tree of minima and maxima (size a power of 2)."""
    step = size // 2
    while step > 0:
        cuda.syncthreads()
        if t < step:
            for a in range(3):
                lo[a, t] = min(lo[a, t], lo[a, t + step])
                hi[a, t] = max(hi[a, t], hi[a, t + step])
        step //= 2
    cuda.syncthreads()


@compiled.cuda_jit()
def _bounds_parts(spheres, n, parts):
    """parts[b] (lo x, y, z, hi x, y, z): the box of the centres block b's
    threads strode over (every gridDim.x * THREADS-th of the first n)."""
    t = cuda.threadIdx.x
    lo = cuda.shared.array((3, THREADS), np.float32)
    hi = cuda.shared.array((3, THREADS), np.float32)
    _empty_box(lo, hi, t)
    for i in range(cuda.blockIdx.x * THREADS + t, n, cuda.gridDim.x * THREADS):
        cx, cy, cz, _, _, _ = _extent(spheres, i)
        lo[0, t], lo[1, t], lo[2, t] = min(lo[0, t], cx), min(lo[1, t], cy), min(lo[2, t], cz)
        hi[0, t], hi[1, t], hi[2, t] = max(hi[0, t], cx), max(hi[1, t], cy), max(hi[2, t], cz)
    _reduce_box(lo, hi, t, THREADS)
    if t < 3:
        parts[cuda.blockIdx.x, t] = lo[t, 0]
        parts[cuda.blockIdx.x, 3 + t] = hi[t, 0]


@compiled.cuda_jit()
def _bounds_merge(parts, count, bounds):
    """bounds (6,): the union of parts[0:count]; one block."""
    t = cuda.threadIdx.x
    lo = cuda.shared.array((3, ONE_BLOCK), np.float32)
    hi = cuda.shared.array((3, ONE_BLOCK), np.float32)
    _empty_box(lo, hi, t)
    for k in range(t, count, ONE_BLOCK):
        for a in range(3):
            lo[a, t] = min(lo[a, t], parts[k, a])
            hi[a, t] = max(hi[a, t], parts[k, 3 + a])
    _reduce_box(lo, hi, t, ONE_BLOCK)
    if t < 3:
        bounds[t] = lo[t, 0]
        bounds[3 + t] = hi[t, 0]


@cuda.jit(device=True)
def _spread(v):
    """The 10 bits of v spread to every third bit (bit k to bit 3k)."""
    v = (v * 0x00010001) & 0xFF0000FF
    v = (v * 0x00000101) & 0x0F00F00F
    v = (v * 0x00000011) & 0xC30C30C3
    return (v * 0x00000005) & 0x49249249


@cuda.jit(device=True)
def _cell(c, lo, hi):
    """The cell (0 .. AXIS_CELLS - 1) of coordinate c in [lo, hi]."""
    if hi > lo:
        return min(np.int64((c - lo) * (np.float32(AXIS_CELLS) / (hi - lo))), AXIS_CELLS - 1)
    return np.int64(0)


@compiled.cuda_jit()
def _morton(spheres, n, bounds, keys, values):
    """keys[i]: the Morton code of centre i in the bounds; values[i] = i."""
    i = cuda.grid(1)
    if i < n:
        cx, cy, cz, _, _, _ = _extent(spheres, i)
        x = _cell(cx, bounds[0], bounds[3])
        y = _cell(cy, bounds[1], bounds[4])
        z = _cell(cz, bounds[2], bounds[5])
        keys[i] = np.uint32((_spread(x) << 2) | (_spread(y) << 1) | _spread(z))
        values[i] = i


@compiled.cuda_jit()
def _count(keys, n, shift, hist, blocks):
    """hist[d * blocks + b]: the keys of tile b whose digit at shift is d."""
    b = cuda.blockIdx.x
    t = cuda.threadIdx.x
    h = cuda.shared.array(RADIX, np.int32)
    for d in range(t, RADIX, SORT_THREADS):
        h[d] = 0
    cuda.syncthreads()
    base = b * SORT_TILE
    for k in range(ITEMS):
        i = base + k * SORT_THREADS + t
        if i < n:
            cuda.atomic.add(h, np.int64(keys[i] >> shift) & DIGIT_MASK, 1)
    cuda.syncthreads()
    for d in range(t, RADIX, SORT_THREADS):
        hist[d * blocks + b] = h[d]


@cuda.jit(device=True)
def _block_scan(sums, t, size):
    """sums[0:size] to its inclusive prefix sums, in place, by the block's
    first `size` threads (every thread of the block must call it)."""
    step = 1
    while step < size:
        cuda.syncthreads()
        v = sums[t - step] if t >= step and t < size else 0
        cuda.syncthreads()
        if t < size:
            sums[t] += v
        step *= 2
    cuda.syncthreads()


@compiled.cuda_jit()
def _scan(hist, m):
    """hist[0:m] to its exclusive prefix sums; one block, each thread a run
    of consecutive entries."""
    t = cuda.threadIdx.x
    sums = cuda.shared.array(ONE_BLOCK, np.int32)
    per = (m + ONE_BLOCK - 1) // ONE_BLOCK
    lo = min(t * per, m)
    hi = min(lo + per, m)
    s = 0
    for i in range(lo, hi):
        s += hist[i]
    sums[t] = s
    _block_scan(sums, t, ONE_BLOCK)
    run = sums[t] - s
    for i in range(lo, hi):
        v = hist[i]
        hist[i] = run
        run += v


@compiled.cuda_jit()
def _scatter(keys, values, n, shift, offsets, blocks, keys_out, values_out):
    """Each key of tile b (with its value) to its place by the digit at
    shift: offsets[d * blocks + b] (the scanned histograms) plus the keys of
    digit d before it in the tile. Stable: thread t takes the tile's keys
    t * ITEMS to (t + 1) * ITEMS - 1, and its place among a digit's keys
    counts those of the threads before it."""
    b = cuda.blockIdx.x
    t = cuda.threadIdx.x
    tile_k = cuda.shared.array(SORT_TILE, np.uint32)
    tile_v = cuda.shared.array(SORT_TILE, np.int32)
    cells = cuda.shared.array(SORT_CELLS, np.int32)  # digit-major: cells[d * SORT_THREADS + thread]
    sums = cuda.shared.array(SORT_THREADS, np.int32)
    start = cuda.shared.array(RADIX, np.int32)
    base = b * SORT_TILE
    for k in range(ITEMS):  # coalesced loads
        j = k * SORT_THREADS + t
        if base + j < n:
            tile_k[j] = keys[base + j]
            tile_v[j] = values[base + j]
    for d in range(RADIX):
        cells[d * SORT_THREADS + t] = 0
    cuda.syncthreads()
    for k in range(ITEMS):
        j = t * ITEMS + k
        if base + j < n:
            cells[(np.int64(tile_k[j] >> shift) & DIGIT_MASK) * SORT_THREADS + t] += 1
    cuda.syncthreads()
    # cells to their exclusive prefix sums in digit-major order: each
    # thread a run of RADIX of them, then the runs' totals scanned
    per = SORT_CELLS // SORT_THREADS
    s = 0
    for c in range(t * per, (t + 1) * per):
        s += cells[c]
    sums[t] = s
    _block_scan(sums, t, SORT_THREADS)
    run = sums[t] - s
    for c in range(t * per, (t + 1) * per):
        v = cells[c]
        cells[c] = run
        run += v
    cuda.syncthreads()
    for d in range(t, RADIX, SORT_THREADS):
        start[d] = cells[d * SORT_THREADS]
    cuda.syncthreads()
    for k in range(ITEMS):
        j = t * ITEMS + k
        if base + j < n:
            d = np.int64(tile_k[j] >> shift) & DIGIT_MASK
            c = d * SORT_THREADS + t
            to = offsets[d * blocks + b] + cells[c] - start[d]
            cells[c] += 1
            keys_out[to] = tile_k[j]
            values_out[to] = tile_v[j]


@compiled.cuda_jit()
def _hierarchy(keys, n, links, up, leaf_up, span):
    """Internal node i (row i) from the sorted keys: bvh.lbvh_steps's hierarchy_row."""
    i = cuda.grid(1)
    if i < n - 1:
        _hierarchy_row(keys, n, i, links, up, leaf_up, span)


@cuda.jit(device=True)
def _load_f(a, i):
    """a[i] (float32) through L2: an atomic that adds nothing."""
    return cuda.atomic.add(a, i, np.float32(0))


@cuda.jit(device=True)
def _load_i(a, i):
    """a[i] (int32) through L2: an atomic that adds nothing."""
    return cuda.atomic.add(a, i, np.int32(0))


@cuda.jit(device=True)
def _arrive(arrived, row):
    """A child's arrival at row: the arrivals before it."""
    cuda.threadfence()  # the box and the rest are seen before the count
    return cuda.atomic.add(arrived, row, 1)


# Karras's hierarchy row, a leaf's climb, the treelet step and the reorder, written once
# (bvh/lbvh_steps.py): compiled here for the GPU, and by numba.njit for the
# CPU model of this build (bvh/lbvh_model.py). Their target is numba.cuda
# (its local.array and clz); under the simulator, which swaps its own cuda in
# for the numba.cuda a function names in its globals only, the CPU's (the
# same answers: np.empty and a count of leading zeros).
_target = lbvh_steps.cpu_target(lambda f: f) if _SIM else cuda


@functools.cache
def _made(primitive=sphere):
    """lbvh_steps for the GPU, for one kind of primitive (another's in a copy: cuda/kinds.py)."""
    return lbvh_steps.make(cuda.jit(device=True), _target, _load_f, _load_i, _arrive, primitive)


_steps = _made()
_hierarchy_row = _steps.hierarchy_row
_reorder_one = _steps.reorder_one
# The primitive's extent as lbvh_steps compiled it: its box's centre is the
# Morton codes' point (_bounds_parts, _morton).
_extent = _steps.extent
_climb = _steps.climb


@compiled.cuda_jit()
def _reorder(spheres, n, order, leaf_up, up, links, kid, span, order_out, leaf_up_out, ordered):
    """After treelets, the spheres in the tree's order (bvh.lbvh_steps's reorder_one, a thread a sphere)."""
    k = cuda.grid(1)
    if k < n:
        _reorder_one(spheres, k, order, leaf_up, up, links, kid, span, order_out, leaf_up_out, ordered)


@compiled.cuda_jit()
def _bounds_up(
    spheres, n, order, leaf_up, up, span, nodes, links, below, costs, kid, arrived, ordered, stats, cost, leaf_max,
    sah, restructure,
):  # fmt: skip
    """Step 5, a thread a leaf: leaf k climbs to the root (bvh.lbvh_steps's climb:
    the boxes, heights, rows and SAH costs bottom-up, the leaves cut, the
    treelets rebuilt where restructure is 1; leaf_max == 0, a refit)."""
    k = cuda.grid(1)
    if k < n:
        _climb(
            spheres, k, order, leaf_up, up, span, nodes, links, below, costs, kid, arrived, ordered, stats, cost,
            leaf_max, sah, restructure,
        )  # fmt: skip


def _kernels() -> SimpleNamespace:
    """The build's kernels that read a primitive, and its module: this module's, or
    a copy's for another kind (compiled.rebound; backends/cuda/kinds.py sets it)."""
    return SimpleNamespace(primitive=sphere, bounds_parts=_bounds_parts, morton=_morton, reorder=_reorder,
                           bounds_up=_bounds_up)  # fmt: skip


@dataclass
class GpuTree:
    """A tree on the device, in raybench.bvh's layout: what the walks read."""

    nodes: object  # device (M, NODE_FLOATS) float32
    links: object  # its int32 view
    ordered: object  # device (LEAF_ROWS, N) float32: the leaf buffer
    order: object  # device (N,) int32
    count: int
    depth: int
    build_s: float
    built_on: str  # "gpu", or "host" (under two spheres, or the GPU's tree too deep)

    @property
    def node_count(self) -> int:
        return self.nodes.shape[0]

    def to_host(self) -> bvh_mod.Bvh:
        """The tree copied to the host, as raybench.bvh's Bvh (for checks and its SAH cost)."""
        nodes = self.nodes.copy_to_host()
        return bvh_mod.Bvh(
            nodes=nodes,
            links=nodes.view(np.int32),
            ordered=self.ordered.copy_to_host()[:, : self.count],
            order=self.order.copy_to_host()[: self.count],
            depth=self.depth,
            build_s=self.build_s,
        )


class Builder:
    """Builds (and refits) trees of n spheres on the GPU, its device arrays
    allocated once and reused by every build and refit: the dynamic case
    builds every frame.

    quality: "sah" (QUALITY, the default) cuts the LBVH into leaves where the
    SAH says, of up to leaf_size spheres (default bvh.LEAF_MAX, as the host's
    builder); "treelet" also rebuilds each row's treelet where the SAH says;
    "lbvh" makes every subtree of up to leaf_size spheres (default
    LEAF_SIZE) a leaf, the first GPU tree, kept to be measured against.
    treelet_passes: the bottom-up passes of treelets of "treelet" (default
    lbvh.TREELET_PASSES). kind: a kind of primitive's _kernels (default the sphere's)."""

    def __init__(self, n: int, leaf_size: int | None = None, quality: str | None = None,
                 treelet_passes: int | None = None, kind: SimpleNamespace | None = None):  # fmt: skip
        self.kind = k = _kernels() if kind is None else kind
        quality = QUALITY if quality is None else quality
        if quality not in QUALITIES:
            raise ValueError(f"quality: must be one of {', '.join(QUALITIES)}, got {quality!r}")
        self.n = n
        self.quality = quality
        self.treelet_passes = lbvh.TREELET_PASSES if treelet_passes is None else treelet_passes
        self.leaf_size = leaf_size if leaf_size is not None else (LEAF_SIZE if quality == "lbvh" else bvh_mod.LEAF_MAX)
        m = max(n - 1, 1)
        self.tiles = _blocks(n, SORT_TILE)
        self.bounds = cuda.device_array(6, np.float32)
        self.bound_parts = cuda.device_array((BOUNDS_BLOCKS, 6), np.float32)
        self.keys = (cuda.device_array(max(n, 1), np.uint32), cuda.device_array(max(n, 1), np.uint32))
        self.values = (cuda.device_array(max(n, 1), np.int32), cuda.device_array(max(n, 1), np.int32))
        self.hist = cuda.device_array(RADIX * self.tiles, np.int32)
        self.nodes = cuda.device_array((m, NODE_FLOATS), np.float32)
        self.links = self.nodes.view(np.int32)
        self.up = cuda.device_array(m, np.int64)
        # the leaves' links up in the sort's order, and in the tree's
        # (after _reorder; refits climb from these)
        self.sorted_up = cuda.device_array(max(n, 1), np.int64)
        self.leaf_up = cuda.device_array(max(n, 1), np.int64) if quality == "treelet" else self.sorted_up
        self.span = cuda.device_array((m, 2), np.int32)
        self.below = cuda.device_array(4 * m, np.int32)
        self.costs = cuda.device_array(2 * m, np.float32)
        self.kid = cuda.device_array(2 * m, np.int32)
        self.arrived = cuda.to_device(np.zeros(m, np.int32))  # each pass leaves it zero
        self.ordered = cuda.device_array((k.primitive.LEAF_ROWS, max(n, 1)), np.float32)
        self.stats = cuda.device_array(2, np.int32)  # the root's height and the rows a walk reaches
        self.cost = cuda.device_array(1, np.float32)
        # the sorted values end in the buffer of the last pass: the order
        # (after treelets, the tree's order goes to the other buffer)
        self.sorted = self.values[PASSES % 2]
        self.order = self.values[1 - PASSES % 2] if quality == "treelet" else self.sorted
        # the launches with their arguments converted once (cuda.launch): those
        # on the builder's own arrays, and those on the caller's spheres, kept
        # while the caller passes the same array
        self._own, self._with, self._spheres = Launches(64), Launches(16), None

    def _on(self, spheres) -> Launches:
        if spheres is not self._spheres:
            self._with.clear()
            self._spheres = spheres
        return self._with

    def launch_build(self, spheres) -> None:
        """Queue the build of the first n spheres of the device array spheres
        (7, >= n); nothing waits."""
        self.launch_codes(spheres)
        self.launch_sort()
        self.launch_hierarchy()
        self.launch_bounds(spheres)

    # The steps of a build, apart so that a benchmark can time each.

    def launch_codes(self, spheres) -> None:
        """Steps 1 and 2: the centres' bounds, then each one's Morton code."""
        parts = min(_blocks(self.n, THREADS), BOUNDS_BLOCKS)
        launch = self._on(spheres)
        launch(self.kind.bounds_parts, parts, THREADS, spheres, self.n, self.bound_parts)
        launch(_bounds_merge, 1, ONE_BLOCK, self.bound_parts, parts, self.bounds)
        launch(self.kind.morton, _blocks(self.n, THREADS), THREADS, spheres, self.n, self.bounds, self.keys[0],
               self.values[0])  # fmt: skip

    def launch_sort(self) -> None:
        """Step 3: the (code, index) pairs sorted by code, stably."""
        for p in range(PASSES):
            src, dst = p % 2, 1 - p % 2
            shift = p * DIGIT_BITS
            self._own(_count, self.tiles, SORT_THREADS, self.keys[src], self.n, shift, self.hist, self.tiles)
            self._own(_scan, 1, ONE_BLOCK, self.hist, RADIX * self.tiles)
            self._own(
                _scatter, self.tiles, SORT_THREADS, self.keys[src], self.values[src], self.n, shift, self.hist,
                self.tiles, self.keys[dst], self.values[dst],
            )  # fmt: skip

    def launch_hierarchy(self) -> None:
        """Step 4: the rows' links from the sorted codes."""
        self._own(
            _hierarchy, _blocks(self.n - 1, THREADS), THREADS, self.keys[PASSES % 2], self.n, self.links, self.up,
            self.sorted_up, self.span,
        )  # fmt: skip

    def launch_bounds(self, spheres) -> None:
        """Step 5: the boxes bottom-up, and the leaves cut (and treelets
        rebuilt, then the spheres put in the tree's order)."""
        self._up(spheres, self.sorted, self.sorted_up, self.leaf_size)
        if self.quality == "treelet":
            for _ in range(self.treelet_passes - 1):  # the treelets of the tree the last pass left
                self._up(spheres, self.sorted, self.sorted_up, self.leaf_size)
            self._on(spheres)(
                self.kind.reorder, _blocks(self.n, THREADS), THREADS, spheres, self.n, self.sorted, self.sorted_up,
                self.up, self.links, self.kid, self.span, self.order, self.leaf_up, self.ordered,
            )  # fmt: skip

    def launch_refit(self, spheres) -> None:
        """Queue the boxes of the tree's rows recomputed from the spheres'
        positions now (the tree's shape kept); nothing waits."""
        self._up(spheres, self.order, self.leaf_up, 0)

    def _up(self, spheres, order, leaf_up, leaf_max: int) -> None:
        self._on(spheres)(
            self.kind.bounds_up, _blocks(self.n, THREADS), THREADS, spheres, self.n, order, leaf_up, self.up, self.span,
            self.nodes, self.links, self.below, self.costs, self.kid, self.arrived, self.ordered, self.stats,
            self.cost, leaf_max, int(self.quality != "lbvh"), int(self.quality == "treelet"),
        )  # fmt: skip

    def read_cost(self) -> float:
        """The tree's SAH cost (bvh.cost.sah_cost's, summed bottom-up on the
        device in float32; waits for the queued work)."""
        return float(self.cost.copy_to_host()[0])

    def read_depth(self) -> int:
        """The tree's depth (waits for the queued work)."""
        return int(self.stats.copy_to_host()[0])

    def read_rows(self) -> int:
        """The rows a walk reaches from the root (the collapsed subtrees'
        rows not counted; waits for the queued work)."""
        return int(self.stats.copy_to_host()[1])

    def tree(self, depth: int, build_s: float) -> GpuTree:
        return GpuTree(self.nodes, self.links, self.ordered, self.order, self.n, depth, build_s, "gpu")


def upload(b: bvh_mod.Bvh) -> GpuTree:
    """A host-built tree on the device."""
    nodes = cuda.to_device(b.nodes)
    return GpuTree(
        nodes,
        nodes.view(np.int32),
        cuda.to_device(b.ordered if b.count else np.zeros((b.ordered.shape[0], 1), np.float32)),
        cuda.to_device(b.order if b.count else np.zeros(1, np.int32)),
        b.count,
        b.depth,
        b.build_s,
        "host",
    )


def build(spheres: np.ndarray, d_spheres, builder: Builder | None = None, max_depth: int = MAX_DEPTH,
          kind: SimpleNamespace | None = None) -> GpuTree:  # fmt: skip
    """The tree of the (7, N) spheres, whose copy on the device is d_spheres,
    built on the GPU (with `builder`'s arrays if given, for N spheres), or on
    the host where the GPU has nothing to build (N < 2) or its tree is deeper
    than max_depth. build_s: from the first launch to the tree ready to walk.
    kind: Builder's, for another kind's buffer (builder's, if given)."""
    kind = builder.kind if builder is not None else (_kernels() if kind is None else kind)
    n = spheres.shape[1]
    if n < 2:
        return upload(bvh_mod.build(spheres, device="cuda", primitive=kind.primitive))
    start = time.perf_counter()
    builder = builder if builder is not None and builder.n == n else Builder(n, kind=kind)
    builder.launch_build(d_spheres)
    depth = builder.read_depth()
    if depth > max_depth:
        return upload(bvh_mod.build(spheres, device="cuda", primitive=kind.primitive))
    return builder.tree(depth, time.perf_counter() - start)
