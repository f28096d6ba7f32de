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

import math
import time
from dataclasses import dataclass

import numpy as np
from numba import config, cuda

from ... import bvh as bvh_mod
from ... import compiled
from ...bvh import lbvh
from ...bvh.lbvh import AXIS_CELLS, CODE_BITS, LEAF_SIZE, REFIT_LIMIT  # noqa: F401 - read as cuda_build.*
from ...layout import BOX_FLOATS, COUNT, INNER, MAX_DEPTH, NODE_FLOATS, PAD, REF
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
#           docs/gpu-build.md#measured-on-the-h200-leases-x2-and-x4).
#   "sah":  a subtree of at most bvh.LEAF_MAX spheres is a leaf where its
#           SAH cost as a leaf is no more than as a row with the best cut
#           below it (the host's builder weighs the same, greedily), decided
#           bottom-up in the pass that fits the boxes, at no extra launch.
#   "treelet": "sah", and each row's subtree first made the cheapest tree
#           over its treelet of TREELET pieces (_treelet, Karras and Aila
#           2013, one pass bottom-up), then the spheres put in the new tree's
#           order (_reorder, one launch more).
QUALITIES = ("sah", "treelet", "lbvh")
QUALITY = lbvh.QUALITY
# A treelet's pieces. Its programme weighs 3^K / 2 splits a row, in local
# arrays of 2^K entries (25 bytes each). The model of this build
# (benchmarks/gpu_tree_model.py), at 100,000 spheres: SAH cost over the
# host's 1.031 with 6 pieces, 1.026 with 8 (3.6 times the splits); pieces
# kept in their Morton order instead (an interval programme, no reorder)
# gave 1.070 whatever their number.
TREELET = 6
SUBSETS = 1 << TREELET
# Bottom-up passes of treelets: each pass more lowers the cost less (the
# model at 100,000 spheres: 1.031, 1.026, 1.025 times the host's after 1, 2,
# 3), each a launch of the bottom-up pass and its treelets' work again.
TREELET_PASSES = 1
# A treelet is rebuilt where that lowers its cost below _GAIN times what it
# was: rounding alone never changes a tree (all spheres at one point stay a
# balanced tree).
_GAIN = np.float32(0.999)
_INF = np.float32(np.inf)
# Device bytes a Builder holds per sphere: keys and values twice (the sort's
# two buffers), the links up (8 + 8), the rows' spans (8), what lies below
# each child (heights and rows 16, costs 8, rows 8), the counters (4), the
# node rows (64) and the ordered spheres (16); the histograms add under 1;
# treelets add the leaves' links up in the tree's order (8).
DEVICE_SPHERE_BYTES = 16 + 16 + 48 + 4 + NODE_FLOATS * 4 + 16 + 1
# The padding of a sphere's box, as raybench.bvh.sphere_pad computes it.
_PAD = PAD
_BOX = BOX_FLOATS
_INNER = INNER
_REF = REF
_COUNT = COUNT
_NODE_COST = bvh_mod.NODE_COST


def _blocks(n: int, per: int) -> int:
    return max(1, math.ceil(n / per))


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
    for a in range(3):
        lo[a, t] = np.float32(np.inf)
        hi[a, t] = np.float32(-np.inf)
    for i in range(cuda.blockIdx.x * THREADS + t, n, cuda.gridDim.x * THREADS):
        for a in range(3):
            v = spheres[a, i]
            lo[a, t] = min(lo[a, t], v)
            hi[a, t] = max(hi[a, t], v)
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
    for a in range(3):
        lo[a, t] = np.float32(np.inf)
        hi[a, t] = np.float32(-np.inf)
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
        x = _cell(spheres[0, i], bounds[0], bounds[3])
        y = _cell(spheres[1, i], bounds[1], bounds[4])
        z = _cell(spheres[2, i], bounds[2], bounds[5])
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


@cuda.jit(device=True)
def _delta(keys, n, i, j):
    """Karras's delta: the length of the common prefix of keys i and j (code
    bits, then place bits where the codes are equal); -1 off the ends."""
    if j < 0 or j >= n:
        return -1
    a = keys[i]
    b = keys[j]
    if a != b:
        return cuda.clz(np.uint32(a ^ b))
    return 32 + cuda.clz(np.uint32(i ^ j))


@compiled.cuda_jit()
def _hierarchy(keys, n, links, up, leaf_up, span):
    """Internal node i (row i): the range of sorted keys it covers, where it
    splits, and its two children (Karras 2012, figure 4): a child of one
    sphere a leaf of it, a child of more the row it starts (collapsed into a
    leaf, or not, by _bounds_up, once its box is known). up[row] and
    leaf_up[leaf]: the parent's row times 2 plus the child's slot (the
    root's: -1). span[row]: the first sphere it covers and their count."""
    i = cuda.grid(1)
    if i >= n - 1:
        return
    # the direction of the range: towards the neighbour sharing more bits
    d = 1 if _delta(keys, n, i, i + 1) > _delta(keys, n, i, i - 1) else -1
    least = _delta(keys, n, i, i - d)
    # an upper bound of the range's length, then the length by binary search
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
    # the split: the last key sharing more than `node` bits with key i
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
    if first == gamma:
        links[i, _REF] = first
        links[i, _COUNT] = 1
        leaf_up[gamma] = 2 * i
    else:
        links[i, _REF] = gamma
        links[i, _COUNT] = _INNER
        up[gamma] = 2 * i
    if last == gamma + 1:
        links[i, _REF + 1] = gamma + 1
        links[i, _COUNT + 1] = 1
        leaf_up[gamma + 1] = 2 * i + 1
    else:
        links[i, _REF + 1] = gamma + 1
        links[i, _COUNT + 1] = _INNER
        up[gamma + 1] = 2 * i + 1
    if i == 0:
        up[0] = -1


@cuda.jit(device=True)
def _half_area(lx, ly, lz, hx, hy, hz):
    dx, dy, dz = max(hx - lx, np.float32(0)), max(hy - ly, np.float32(0)), max(hz - lz, np.float32(0))
    return dx * dy + dy * dz + dz * dx


@cuda.jit(device=True)
def _load_f(a, i):
    """a[i] (float32) through L2: an atomic that adds nothing."""
    return cuda.atomic.add(a, i, np.float32(0))


@cuda.jit(device=True)
def _load_i(a, i):
    """a[i] (int32) through L2: an atomic that adds nothing."""
    return cuda.atomic.add(a, i, np.int32(0))


@cuda.jit(device=True)
def _entry(nodes, links, span, kid, below, costs, row, slot, e, tb, tn, tc, th, tw, tref, tcnt, trow):
    """Piece e of a treelet: child slot of row (its box, link, row below,
    cost, height, rows below, spheres), read by atomics that add nothing:
    other threads wrote them, and a plain load could find a stale line in
    this SM's L1."""
    link = 2 * row + slot
    for q in range(6):
        tb[e, q] = _load_f(nodes, (row, 6 * slot + q))
    tref[e] = _load_i(links, (row, _REF + slot))
    tcnt[e] = _load_i(links, (row, _COUNT + slot))
    trow[e] = _load_i(kid, link)
    tc[e] = _load_f(costs, link)
    th[e] = _load_i(below, 2 * link)
    tw[e] = _load_i(below, 2 * link + 1)
    tn[e] = _load_i(span, (trow[e], 1)) if trow[e] >= 0 else 1


@cuda.jit(device=True)
def _union(tb, part, size):
    """The box of the pieces in the bit set part."""
    lx = ly = lz = _INF
    hx = hy = hz = -_INF
    for e in range(size):
        if part & (1 << e):
            lx, ly, lz = min(lx, tb[e, 0]), min(ly, tb[e, 1]), min(lz, tb[e, 2])
            hx, hy, hz = max(hx, tb[e, 3]), max(hy, tb[e, 4]), max(hz, tb[e, 5])
    return lx, ly, lz, hx, hy, hz


@cuda.jit(device=True)
def _piece(part):
    """The piece of a set of one."""
    e = 0
    while (1 << e) != part:
        e += 1
    return e


@cuda.jit(device=True)
def _treelet(x, old, nodes, links, span, up, leaf_up, kid, below, costs, leaf_max):
    """Row x's subtree (its rows' boxes, links and costs final) made the
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
    x is changed only where the cost falls below _GAIN times old (x's cost
    as it is), so that rounding never churns equal trees. Returns (cost,
    height, rows) of x after, or (old, -1, -1) where nothing changed."""
    K = TREELET
    tb = cuda.local.array((TREELET, 6), np.float32)
    tn = cuda.local.array(TREELET, np.int32)
    tc = cuda.local.array(TREELET, np.float32)
    th = cuda.local.array(TREELET, np.int32)
    tw = cuda.local.array(TREELET, np.int32)
    tref = cuda.local.array(TREELET, np.int32)
    tcnt = cuda.local.array(TREELET, np.int32)
    trow = cuda.local.array(TREELET, np.int32)
    rows = cuda.local.array(TREELET, np.int32)
    area = cuda.local.array(SUBSETS, np.float32)
    cnt = cuda.local.array(SUBSETS, np.int32)
    cost = cuda.local.array(SUBSETS, np.float32)
    split = cuda.local.array(SUBSETS, np.int32)
    hh = cuda.local.array(SUBSETS, np.int32)
    ww = cuda.local.array(SUBSETS, np.int32)
    leaf = cuda.local.array(SUBSETS, np.int8)
    stack = cuda.local.array((TREELET, 2), np.int32)
    rows[0] = x
    used = 1
    _entry(nodes, links, span, kid, below, costs, x, 0, 0, tb, tn, tc, th, tw, tref, tcnt, trow)
    _entry(nodes, links, span, kid, below, costs, x, 1, 1, tb, tn, tc, th, tw, tref, tcnt, trow)
    size = 2
    while size < K:
        best = -1
        best_area = np.float32(-1)
        for e in range(size):
            if tcnt[e] == _INNER:
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
        best = _INF
        at = low
        p = (sm - 1) & sm
        while p > 0:
            if p & low:  # each split once: the side with the lowest piece first
                v = cost[p] + cost[sm ^ p]
                if v < best:
                    best = v
                    at = p
            p = (p - 1) & sm
        inner = _NODE_COST * area[sm] + best
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
    if not cost[full] < old * _GAIN:
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
                links[row, _REF + slot] = tref[e]
                links[row, _COUNT + slot] = tcnt[e]
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
                links[row, _REF + slot] = -1  # set by _reorder
                links[row, _COUNT + slot] = cnt[part]
            else:
                links[row, _REF + slot] = child
                links[row, _COUNT + slot] = _INNER
            stack[top, 0] = part
            stack[top, 1] = child
            top += 1
    return cost[full], hh[full], ww[full]


@compiled.cuda_jit()
def _reorder(spheres, n, order, leaf_up, up, links, kid, span, order_out, leaf_up_out, ordered):
    """After treelets, the spheres in the tree's order, so that every leaf
    is again a range of them: leaf k's place is the spheres left of it in
    the tree (on its way up, the left sibling's count wherever it is a right
    child). Its sphere, its index and its link up go there; on the way up
    while it is the leftmost sphere of the child it climbs from, it sets
    that child's ref where the child is a leaf (every leaf has one leftmost
    sphere)."""
    k = cuda.grid(1)
    if k >= n:
        return
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
        if links[row, _COUNT + slot] != _INNER:
            links[row, _REF + slot] = rank
        if slot == 1:
            break
        link = up[row]


@compiled.cuda_jit()
def _bounds_up(
    spheres, n, order, leaf_up, up, span, nodes, links, below, costs, kid, arrived, ordered, stats, cost, leaf_max,
    sah, restructure,
):  # fmt: skip
    """Leaf k (its sphere order[k]) climbs to the root, each row's box
    written into its parent's slot; a row's second child to arrive (arrived
    counts them) unites the two boxes and climbs on, and sets the counter
    back to 0 for the next pass. Also writes leaf k's sphere into ordered
    (the scene's values).

    On the way up, per child (index 2 * row + slot), what the walks see below
    it: below[2 * index] its height (a leaf 0, a row 1 + its children's
    most), below[2 * index + 1] the rows a walk reaches from it (a leaf 0),
    costs[index] its SAH cost unnormalised (a leaf: count x its box's half
    area; a row: NODE_COST x its half area plus its children's); stats: the
    root's height and rows, cost[0] the tree's SAH cost (bvh.cost.sah_cost's).

    leaf_max > 0 (a build): the second arrival at a row of at most leaf_max
    spheres makes it a leaf of them in its parent's slot (they are
    consecutive: an LBVH row covers a range of the leaf order) where sah is
    0, or where sah is 1 and the SAH says a leaf is cheaper than the row
    with the best choice below it (a leaf's cost against the row's: the
    optimal cut of this tree into leaves, as each row's cost is the cheapest
    of its subtree's). Its rows stay, out of the walks' reach, so that
    refits still climb through them. Where restructure is 1, each row's
    subtree is first made the cheapest over its treelet (_treelet; kid[index]
    is the row below each child, -1 for a sphere). leaf_max == 0 (a refit):
    the links are kept, and the costs are the tree's as it is."""
    k = cuda.grid(1)
    if k >= n:
        return
    s = order[k]
    cx, cy, cz, r = spheres[0, s], spheres[1, s], spheres[2, s], spheres[3, s]
    ordered[0, k] = cx
    ordered[1, k] = cy
    ordered[2, k] = cz
    ordered[3, k] = r
    pr = r + (r + (abs(cx) + abs(cy) + abs(cz))) * _PAD
    lx, ly, lz, hx, hy, hz = cx - pr, cy - pr, cz - pr, cx + pr, cy + pr, cz + pr
    h = 0
    w = 0
    c = _half_area(lx, ly, lz, hx, hy, hz)  # a leaf of one sphere
    a = c
    cur = -1
    link = leaf_up[k]
    while link >= 0:
        row = link // 2
        slot = link - 2 * row
        col = slot * _BOX
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
        cuda.threadfence()  # the box and the rest are seen before the count
        if cuda.atomic.add(arrived, row, 1) == 0:
            return  # the sibling, arriving second, goes on
        other = (1 - slot) * _BOX
        sib = 2 * row + 1 - slot
        lx = min(lx, cuda.atomic.add(nodes, (row, other), np.float32(0)))
        ly = min(ly, cuda.atomic.add(nodes, (row, other + 1), np.float32(0)))
        lz = min(lz, cuda.atomic.add(nodes, (row, other + 2), np.float32(0)))
        hx = max(hx, cuda.atomic.add(nodes, (row, other + 3), np.float32(0)))
        hy = max(hy, cuda.atomic.add(nodes, (row, other + 4), np.float32(0)))
        hz = max(hz, cuda.atomic.add(nodes, (row, other + 5), np.float32(0)))
        h = 1 + max(h, cuda.atomic.add(below, 2 * sib, np.int32(0)))
        w = 1 + w + cuda.atomic.add(below, 2 * sib + 1, np.int32(0))
        # the two children's sum first: the same whichever arrived first
        a = _half_area(lx, ly, lz, hx, hy, hz)
        c = _NODE_COST * a + (c + cuda.atomic.add(costs, sib, np.float32(0)))
        arrived[row] = 0
        cur = row
        if restructure != 0 and leaf_max > 0 and span[row, 1] > 2:  # two spheres have one tree
            tc, th, tw = _treelet(row, c, nodes, links, span, up, leaf_up, kid, below, costs, leaf_max)
            if th >= 0:
                c, h, w = tc, th, tw
        link = up[row]
        if link >= 0:
            parent = link // 2
            pslot = link - 2 * parent
            count = span[row, 1]
            leaf = np.float32(count) * a
            if count <= leaf_max and (sah == 0 or leaf <= c):
                links[parent, _REF + pslot] = span[row, 0]
                links[parent, _COUNT + pslot] = count
            if links[parent, _COUNT + pslot] != _INNER:
                h = 0
                w = 0
                c = leaf
    stats[0] = h
    stats[1] = w
    cost[0] = c / a if a > 0 else np.float32(0)


@dataclass
class GpuTree:
    """A tree on the device, in raybench.bvh's layout: what the walks read."""

    nodes: object  # device (M, NODE_FLOATS) float32
    links: object  # its int32 view
    ordered: object  # device (4, N) float32
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
    LEAF_SIZE) a leaf, the first GPU tree, kept to be measured against."""

    def __init__(self, n: int, leaf_size: int | None = None, quality: str | None = None):
        quality = QUALITY if quality is None else quality
        if quality not in QUALITIES:
            raise ValueError(f"quality: must be one of {', '.join(QUALITIES)}, got {quality!r}")
        self.n = n
        self.quality = quality
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
        self.ordered = cuda.device_array((4, max(n, 1)), np.float32)
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
        launch(_bounds_parts, parts, THREADS, spheres, self.n, self.bound_parts)
        launch(_bounds_merge, 1, ONE_BLOCK, self.bound_parts, parts, self.bounds)
        launch(_morton, _blocks(self.n, THREADS), THREADS, spheres, self.n, self.bounds, self.keys[0], self.values[0])

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
            for _ in range(TREELET_PASSES - 1):  # the treelets of the tree the last pass left
                self._up(spheres, self.sorted, self.sorted_up, self.leaf_size)
            self._on(spheres)(
                _reorder, _blocks(self.n, THREADS), THREADS, spheres, self.n, self.sorted, self.sorted_up, self.up,
                self.links, self.kid, self.span, self.order, self.leaf_up, self.ordered,
            )  # fmt: skip

    def launch_refit(self, spheres) -> None:
        """Queue the boxes of the tree's rows recomputed from the spheres'
        positions now (the tree's shape kept); nothing waits."""
        self._up(spheres, self.order, self.leaf_up, 0)

    def _up(self, spheres, order, leaf_up, leaf_max: int) -> None:
        self._on(spheres)(
            _bounds_up, _blocks(self.n, THREADS), THREADS, spheres, self.n, order, leaf_up, self.up, self.span,
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
        cuda.to_device(b.ordered if b.count else np.zeros((4, 1), np.float32)),
        cuda.to_device(b.order if b.count else np.zeros(1, np.int32)),
        b.count,
        b.depth,
        b.build_s,
        "host",
    )


def build(spheres: np.ndarray, d_spheres, builder: Builder | None = None, max_depth: int = MAX_DEPTH) -> GpuTree:
    """The tree of the (7, N) spheres, whose copy on the device is d_spheres,
    built on the GPU (with `builder`'s arrays if given, for N spheres), or on
    the host where the GPU has nothing to build (N < 2) or its tree is deeper
    than max_depth. build_s: from the first launch to the tree ready to walk."""
    n = spheres.shape[1]
    if n < 2:
        return upload(bvh_mod.build(spheres, device="cuda"))
    start = time.perf_counter()
    builder = builder if builder is not None and builder.n == n else Builder(n)
    builder.launch_build(d_spheres)
    depth = builder.read_depth()
    if depth > max_depth:
        return upload(bvh_mod.build(spheres, device="cuda"))
    return builder.tree(depth, time.perf_counter() - start)
