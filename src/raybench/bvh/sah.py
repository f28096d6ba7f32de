"""The BVH's builder on the host: binned SAH over the spheres, compiled with Numba.

Top-down binned SAH (surface area heuristic).
An LBVH (Morton codes) builds faster on a GPU, but its splits fall at fixed
spatial midpoints whatever the spheres do, and for the benchmark's scenes
(spheres bunched in a view frustum, radii shrinking with the count) that gives
trees a ray walks more nodes of. Binned SAH picks, at every node, the split of
16 candidate planes per axis that minimises the expected cost of a random ray,
in O(n) per level, fast enough for a million spheres (docs/gpu-build.md), and
the trace, done every frame, is what the tree must serve.
Every thread takes part from the root down: a range of many spheres is split
by all of them at once, and smaller ranges are subtrees built one per thread.

Depth is bounded by MAX_DEPTH whatever the input: where SAH splits would go
deeper, the builder splits by count (object median), and spheres whose centres
all coincide are split by count too.
"""

from __future__ import annotations

import sys
import threading
import time
from dataclasses import dataclass

import numba
import numpy as np

from .. import compiled
from ..errors import RaybenchError
from ..host import usable_cores
from ..kernels.primitives import sphere
from ..layout import (
    BOX_FLOATS,
    CHILD_BOX,
    COUNT,
    EMPTY,
    INNER,
    MAX_DEPTH,
    NODE_BYTES,
    NODE_FLOATS,
    REF,
)
from . import oneshot

BINS = 16
LEAF_MAX = 8
# Leaves of up to LEAF_ALWAYS spheres are kept without weighing a split:
# the split would seldom win (a node visit costs about NODE_COST sphere
# tests) and weighing it is most of the build's time at the bottom of the tree.
LEAF_ALWAYS = 3
# Expected cost of visiting a node (two box tests), in sphere tests; the SAH
# weighs splitting against leaving the spheres in one leaf with it.
NODE_COST = np.float32(2.0)
# Ranges of more spheres than WIDE are split by all the build's threads at
# once, each binning and then moving a slice of at most SLICE spheres, so the
# top of a large tree does not wait on one core (_grow_wide); smaller ones are
# whole subtrees, one thread each. WIDE is a count, not a share of the threads,
# so the tree is the same on any number of threads. Wide ranges are binned
# along their centres' widest axis only (Wald 2007): a third of the work where
# the build spends most of it, for trees the walk measures no slower on the
# benchmark's scenes.
WIDE = 4096
SLICE = 1 << 14
# Bytes the builder holds per sphere at its peak: work arrays (the last, the
# order) and their spare set, ordered spheres, two rows of nodes and the
# packed copy.
BUILD_SPHERE_BYTES = 5 * 4 + 5 * 4 + 4 * 4 + 3 * NODE_BYTES
# Per sphere on the device after the build: nodes (at most one per sphere),
# ordered spheres, order.
DEVICE_SPHERE_BYTES = NODE_BYTES + 4 * 4 + 4
MAX_SPHERES = 2**31 - 1
_ONE_BUILD = threading.Lock()


@dataclass
class Bvh:
    nodes: np.ndarray  # (M, 16) float32
    links: np.ndarray  # (M, 16) int32 view of nodes; columns REF, COUNT used
    ordered: np.ndarray  # (4, N) float32: cx, cy, cz, r in leaf order
    order: np.ndarray  # (N,) int32: original index of each ordered sphere
    depth: int  # deepest node (root = 1)
    build_s: float  # seconds the build took (compiled code only, unless interpreted)
    interpreted: bool = False  # built by the builder's Python, uncompiled (one_shot)

    @property
    def count(self) -> int:
        return self.order.shape[0]

    @property
    def node_count(self) -> int:
        return self.nodes.shape[0]


# The padding of a sphere's box, as every builder computes it (the primitive's own rule).
sphere_pad = compiled.njit(nogil=True)(sphere.pad)


@compiled.njit(nogil=True)
def _prepare(cx, cy, cz, r, p, s, e, bounds):
    """The builder's arrays p for the spheres [s, e): centres, padded radii,
    original indices; bounds (12,): their box, then their centres' box."""
    px, py, pz, pr, idx = p
    for i in range(s, e):
        px[i], py[i], pz[i] = cx[i], cy[i], cz[i]
        pr[i] = r[i] + sphere_pad(cx[i], cy[i], cz[i], r[i])
        idx[i] = i
    _range_bounds(px, py, pz, pr, s, e, bounds[:6], bounds[6:])


@compiled.njit(nogil=True)
def _log2ceil(n):
    k = 0
    while (1 << k) < n:
        k += 1
    return k


@compiled.njit(nogil=True)
def _range_bounds(px, py, pz, pr, s, e, box, cbox):
    """box: union of the spheres' padded boxes over [s, e); cbox: bounds of their centres."""
    # in locals, not box[]: stores to an array that may alias px cannot stay in
    # registers (docs/gpu-build.md#figures-moved-from-the-sources-comments)
    inf = np.float32(np.inf)
    lx = ly = lz = clx = cly = clz = inf
    hx = hy = hz = chx = chy = chz = -inf
    for i in range(s, e):
        x, y, z, r = px[i], py[i], pz[i], pr[i]
        lx, ly, lz = min(lx, x - r), min(ly, y - r), min(lz, z - r)
        hx, hy, hz = max(hx, x + r), max(hy, y + r), max(hz, z + r)
        clx, cly, clz = min(clx, x), min(cly, y), min(clz, z)
        chx, chy, chz = max(chx, x), max(chy, y), max(chz, z)
    box[0], box[1], box[2], box[3], box[4], box[5] = lx, ly, lz, hx, hy, hz
    cbox[0], cbox[1], cbox[2], cbox[3], cbox[4], cbox[5] = clx, cly, clz, chx, chy, chz


@compiled.njit(nogil=True)
def _area(lx, ly, lz, hx, hy, hz):
    dx, dy, dz = hx - lx, hy - ly, hz - lz
    return dx * dy + dy * dz + dz * dx


@compiled.njit(nogil=True)
def _swap(px, py, pz, pr, idx, i, j):
    px[i], px[j] = px[j], px[i]
    py[i], py[j] = py[j], py[i]
    pz[i], pz[j] = pz[j], pz[i]
    pr[i], pr[j] = pr[j], pr[i]
    idx[i], idx[j] = idx[j], idx[i]


@compiled.njit(nogil=True)
def _median_split(px, py, pz, pr, idx, s, e, cbox):
    """Split [s, e) in two halves by count along the centres' widest axis:
    the first half's centres no greater than the second's. A selection in
    place (Hoare's), not a sort: it compiles in a fraction of the time, and
    the order within each half does not matter to the builder."""
    ext0, ext1, ext2 = cbox[3] - cbox[0], cbox[4] - cbox[1], cbox[5] - cbox[2]
    axis = 0 if ext0 >= ext1 and ext0 >= ext2 else (1 if ext1 >= ext2 else 2)
    m = s + (e - s) // 2
    if max(ext0, max(ext1, ext2)) > 0:
        key = px if axis == 0 else (py if axis == 1 else pz)
        lo, hi = s, e - 1
        while lo < hi:
            pivot = key[lo + (hi - lo) // 2]
            i, j = lo, hi
            while i <= j:
                while key[i] < pivot:
                    i += 1
                while key[j] > pivot:
                    j -= 1
                if i <= j:
                    _swap(px, py, pz, pr, idx, i, j)
                    i += 1
                    j -= 1
            # now key[lo..j] <= pivot <= key[i..hi], and key[j+1..i-1] == pivot
            if m <= j:
                hi = j
            elif m >= i:
                lo = i
            else:
                break
    return m


@compiled.njit(nogil=True, inline="always")
def _clear_bins(counts, bins):
    """Empty bins: columns of (lo, hi) triples, each lo +inf and hi -inf."""
    inf = np.float32(np.inf)
    counts[:] = 0
    for k in range(bins.shape[0]):
        for c in range(0, bins.shape[1], 6):
            for d in range(3):
                bins[k, c + d] = inf
                bins[k, c + 3 + d] = -inf


@compiled.njit(nogil=True, inline="always")
def _best_plane(counts, bins, scale, nb, left_area, left_count):
    """The SAH's best plane among the binned axes (scale[a] > 0): (cost,
    axis, last bin on the left); axis -1 where no plane has spheres on both
    sides."""
    inf = np.float32(np.inf)
    best_cost = inf
    best_axis = -1
    best_bin = 0
    for a in range(3):
        if scale[a] == 0:
            continue
        lx = ly = lz = inf
        hx = hy = hz = -inf
        n = 0
        for k in range(nb - 1):
            lx, ly, lz = min(lx, bins[a, k, 0]), min(ly, bins[a, k, 1]), min(lz, bins[a, k, 2])
            hx, hy, hz = max(hx, bins[a, k, 3]), max(hy, bins[a, k, 4]), max(hz, bins[a, k, 5])
            n += counts[a, k]
            left_area[k] = _area(lx, ly, lz, hx, hy, hz) if n > 0 else np.float32(0.0)
            left_count[k] = n
        lx = ly = lz = inf
        hx = hy = hz = -inf
        n = 0
        for k in range(nb - 1, 0, -1):
            lx, ly, lz = min(lx, bins[a, k, 0]), min(ly, bins[a, k, 1]), min(lz, bins[a, k, 2])
            hx, hy, hz = max(hx, bins[a, k, 3]), max(hy, bins[a, k, 4]), max(hz, bins[a, k, 5])
            n += counts[a, k]
            nl = left_count[k - 1]
            if n == 0 or nl == 0:
                continue
            cost = np.float32(nl) * left_area[k - 1] + np.float32(n) * _area(lx, ly, lz, hx, hy, hz)
            if cost < best_cost:
                best_cost, best_axis, best_bin = cost, a, k - 1
    return best_cost, best_axis, best_bin


@compiled.njit(nogil=True)
def _widest(cbox):
    wide = 0
    for a in range(1, 3):
        if cbox[3 + a] - cbox[a] > cbox[3 + wide] - cbox[wide]:
            wide = a
    return wide


@compiled.njit(nogil=True)
def _sah_split(px, py, pz, pr, idx, s, e, box, cbox, counts, bins, scale, left_area, left_count):
    """Binned SAH: the best of nb-1 planes on each axis (nb = BINS, fewer
    for a few spheres). Returns the split point m (s < m < e) and the
    split's cost relative to the node's area (inf if the centres coincide:
    no plane separates them). counts to left_count: scratch arrays."""
    inf = np.float32(np.inf)
    nb = min(BINS, max(4, e - s))
    for a in range(3):
        ext = cbox[3 + a] - cbox[a]
        scale[a] = np.float32(nb * (1 - 1e-5)) / ext if ext > 0 else np.float32(0.0)
        _clear_bins(counts[a, :nb], bins[a, :nb])
    c0, c1, c2 = cbox[0], cbox[1], cbox[2]
    s0, s1, s2 = scale[0], scale[1], scale[2]
    last = np.uint32(nb - 1)  # unsigned bin indices: no negative-index wraparound to compute
    # the three axes written out: the hot loop of the build
    for i in range(s, e):
        x, y, z, r = px[i], py[i], pz[i], pr[i]
        lx, ly, lz, hx, hy, hz = x - r, y - r, z - r, x + r, y + r, z + r
        k = min(np.uint32((x - c0) * s0), last)
        counts[0, k] += 1
        bins[0, k, 0] = min(bins[0, k, 0], lx)
        bins[0, k, 1] = min(bins[0, k, 1], ly)
        bins[0, k, 2] = min(bins[0, k, 2], lz)
        bins[0, k, 3] = max(bins[0, k, 3], hx)
        bins[0, k, 4] = max(bins[0, k, 4], hy)
        bins[0, k, 5] = max(bins[0, k, 5], hz)
        k = min(np.uint32((y - c1) * s1), last)
        counts[1, k] += 1
        bins[1, k, 0] = min(bins[1, k, 0], lx)
        bins[1, k, 1] = min(bins[1, k, 1], ly)
        bins[1, k, 2] = min(bins[1, k, 2], lz)
        bins[1, k, 3] = max(bins[1, k, 3], hx)
        bins[1, k, 4] = max(bins[1, k, 4], hy)
        bins[1, k, 5] = max(bins[1, k, 5], hz)
        k = min(np.uint32((z - c2) * s2), last)
        counts[2, k] += 1
        bins[2, k, 0] = min(bins[2, k, 0], lx)
        bins[2, k, 1] = min(bins[2, k, 1], ly)
        bins[2, k, 2] = min(bins[2, k, 2], lz)
        bins[2, k, 3] = max(bins[2, k, 3], hx)
        bins[2, k, 4] = max(bins[2, k, 4], hy)
        bins[2, k, 5] = max(bins[2, k, 5], hz)
    best_cost, best_axis, best_bin = _best_plane(counts, bins, scale, nb, left_area, left_count)
    if best_axis < 0:
        return s, inf
    area = _area(box[0], box[1], box[2], box[3], box[4], box[5])
    rel = best_cost / area if area > 0 else np.float32(0.0)
    # partition: the same bin arithmetic as above, so the sides get exactly the counted spheres
    lo = cbox[best_axis]
    sc = scale[best_axis]
    i, j = s, e - 1
    while i <= j:
        c = px[i] if best_axis == 0 else (py[i] if best_axis == 1 else pz[i])
        if min(int((c - lo) * sc), last) <= best_bin:
            i += 1
        else:
            _swap(px, py, pz, pr, idx, i, j)
            j -= 1
    return i, rel


@compiled.njit(nogil=True)
def _push(stack, top, parent, slot, s, e, d):
    stack[top, 0] = parent
    stack[top, 1] = slot
    stack[top, 2] = s
    stack[top, 3] = e
    stack[top, 4] = d
    return top + 1


@compiled.njit(nogil=True)
def _empty_children(nodes, row):
    """Both children's boxes of row inverted (lo EMPTY, hi -EMPTY): empty until filled."""
    for col in CHILD_BOX:
        nodes[row, col : col + 3] = EMPTY
        nodes[row, col + 3 : col + BOX_FLOATS] = -EMPTY


@compiled.njit(nogil=True)
def _root(px, py, pz, pr, idx, nodes, links, stack):
    """Row 0, the root, with its spheres split in two children whatever their
    number; pushes their tasks (parent row, slot, start, end, parent's depth)
    on stack and returns the stack's height."""
    n = px.shape[0]
    box = np.empty(6, np.float32)
    cbox = np.empty(6, np.float32)
    _empty_children(nodes, 0)
    for slot in range(2):
        links[0, REF + slot] = 0
        links[0, COUNT + slot] = 0
    if n == 0:
        return 0
    _range_bounds(px, py, pz, pr, 0, n, box, cbox)
    if n == 1:
        m = 1
    elif 1 + _log2ceil(n) >= MAX_DEPTH:
        m = _median_split(px, py, pz, pr, idx, 0, n, cbox)
    else:
        m, _cost = _sah_split(
            px,
            py,
            pz,
            pr,
            idx,
            0,
            n,
            box,
            cbox,
            np.zeros((3, BINS), np.int64),
            np.empty((3, BINS, 6), np.float32),
            np.empty(3, np.float32),
            np.empty(BINS, np.float32),
            np.empty(BINS, np.int64),
        )
        if m == 0 or m == n:
            m = _median_split(px, py, pz, pr, idx, 0, n, cbox)
    top = _push(stack, 0, 0, 1, m, n, 1)
    return _push(stack, top, 0, 0, 0, m, 1)


@compiled.njit(nogil=True)
def _open_row(nodes, links, parent, slot, row):
    """Make row an inner node, the child (parent, slot), with both its children empty for now."""
    links[parent, REF + slot] = row
    links[parent, COUNT + slot] = INNER
    _empty_children(nodes, row)


@compiled.njit(nogil=True)
def _grow(px, py, pz, pr, idx, nodes, links, stack, top, used):
    """Build the subtrees of the tasks on stack, new rows from `used` on.
    Returns (rows used, deepest depth)."""
    box = np.empty(6, np.float32)
    cbox = np.empty(6, np.float32)
    counts = np.zeros((3, BINS), np.int64)
    bins = np.empty((3, BINS, 6), np.float32)
    scale = np.empty(3, np.float32)
    left_area = np.empty(BINS, np.float32)
    left_count = np.empty(BINS, np.int64)
    depth = 1
    while top > 0:
        top -= 1
        parent, slot, s, e, d = stack[top, 0], stack[top, 1], stack[top, 2], stack[top, 3], stack[top, 4]
        count = e - s
        col = CHILD_BOX[slot]
        links[parent, REF + slot] = s
        links[parent, COUNT + slot] = count
        depth = max(depth, d)
        if count == 0:
            continue  # an empty child: its box stays inverted
        _range_bounds(px, py, pz, pr, s, e, box, cbox)
        for k in range(BOX_FLOATS):
            nodes[parent, col + k] = box[k]
        if count <= LEAF_ALWAYS:
            continue
        if d + 1 + _log2ceil(count) >= MAX_DEPTH:  # deeper SAH splits could overflow the stack
            m = _median_split(px, py, pz, pr, idx, s, e, cbox)
        else:
            m, rel = _sah_split(px, py, pz, pr, idx, s, e, box, cbox, counts, bins, scale, left_area, left_count)
            if count <= LEAF_MAX and (m == s or np.float32(count) <= NODE_COST + rel):
                continue  # a leaf: cheaper than the best split
            if m == s or m == e:  # the centres coincide: split by count
                m = _median_split(px, py, pz, pr, idx, s, e, cbox)
        row = used
        used += 1
        depth = max(depth, d + 1)
        _open_row(nodes, links, parent, slot, row)
        top = _push(stack, top, row, 1, m, e, d + 1)
        top = _push(stack, top, row, 0, s, m, d + 1)
    return used, depth


@compiled.njit(nogil=True)
def _stack():
    """A builder's task stack: (parent row, slot, start, end, depth) rows."""
    return np.empty((2 * MAX_DEPTH + 8, 5), np.int64)


# --- the top of a large tree: each split shared by all threads -----------------------
#
# A level of wide ranges is split in four steps: plan (which axis, how it is
# sliced), bin the slices (threads), choose each range's plane and where each
# slice's spheres go, move them (threads), then attach the children. A slice
# moves its spheres between the two buffers (the builder's arrays and a spare
# set), keeping their order: `buf` says which buffer holds a range now.
# The bins' minima, maxima and counts merge exactly, so a range gets the same
# plane however many slices it was cut into.


@compiled.njit(nogil=True)
def _plan(level, bounds, p, q, piece, axis, lo, scale, mid, first_job):
    """For each wide range of the level, row, s, e, depth, buf: the axis to
    bin (its centres' widest), its bin arithmetic, and mid: -1 for a SAH
    split, else the split point of a split by count (depth guard, or centres
    that coincide). The ranges cut in slices of at most `piece` spheres:
    jobs (J, 3) = range, s, e; first_job[k] is range k's first."""
    jobs = 0
    for k in range(level.shape[0]):
        jobs += (level[k, 2] - level[k, 1] + piece - 1) // piece
    out = np.empty((jobs, 3), np.int64)
    j = 0
    for k in range(level.shape[0]):
        s, e, d, buf = level[k, 1], level[k, 2], level[k, 3], level[k, 4]
        cbox = bounds[k, 6:]
        a = _widest(cbox)
        ext = cbox[3 + a] - cbox[a]
        axis[k] = a
        lo[k] = cbox[a]
        scale[k] = np.float32(BINS * (1 - 1e-5)) / ext if ext > 0 else np.float32(0.0)
        mid[k] = -1
        if ext == 0:
            mid[k] = s + (e - s) // 2
        elif d + _log2ceil(e - s) >= MAX_DEPTH:  # as _grow's guard, for a row at depth d
            x, y, z, r, i = p if buf == 0 else q
            mid[k] = _median_split(x, y, z, r, i, s, e, cbox)
        first_job[k] = j
        for a0 in range(s, e, piece):
            out[j, 0] = k
            out[j, 1] = a0
            out[j, 2] = min(a0 + piece, e)
            j += 1
    first_job[level.shape[0]] = j
    return out


@compiled.njit(nogil=True)
def _bin_jobs(level, jobs, p, q, axis, lo, scale, mid, counts, bins, first, step):
    """Bin the slices jobs[first::step] of SAH ranges along their range's
    axis: counts[j]; bins[j]: each bin's box, then its centres' box."""
    last = BINS - 1
    # each thread bins in its own arrays: bins[j] beside another thread's
    # bins[j + 1] share cache lines, which all the threads write, every sphere
    # (what that cost: docs/gpu-build.md#the-build-on-every-thread-kept)
    n = np.empty(BINS, np.int64)
    b = np.empty((BINS, 12), np.float32)
    for j in range(first, jobs.shape[0], step):
        k = jobs[j, 0]
        if mid[k] >= 0:
            continue
        x, y, z, r, _ = p if level[k, 4] == 0 else q
        a = axis[k]
        key = x if a == 0 else (y if a == 1 else z)
        c, sa = lo[k], scale[k]
        _clear_bins(n, b)
        for i in range(jobs[j, 1], jobs[j, 2]):
            xi, yi, zi, ri = x[i], y[i], z[i], r[i]
            kb = min(int((key[i] - c) * sa), last)
            n[kb] += 1
            b[kb, 0] = min(b[kb, 0], xi - ri)
            b[kb, 1] = min(b[kb, 1], yi - ri)
            b[kb, 2] = min(b[kb, 2], zi - ri)
            b[kb, 3] = max(b[kb, 3], xi + ri)
            b[kb, 4] = max(b[kb, 4], yi + ri)
            b[kb, 5] = max(b[kb, 5], zi + ri)
            b[kb, 6] = min(b[kb, 6], xi)
            b[kb, 7] = min(b[kb, 7], yi)
            b[kb, 8] = min(b[kb, 8], zi)
            b[kb, 9] = max(b[kb, 9], xi)
            b[kb, 10] = max(b[kb, 10], yi)
            b[kb, 11] = max(b[kb, 11], zi)
        counts[j] = n
        bins[j] = b


@compiled.njit(nogil=True)
def _merge(into, bins):
    """into (12,) |= bins (m, 12): lows by min, highs by max."""
    for b in range(bins.shape[0]):
        for c in range(0, 12, 6):
            for d in range(3):
                into[c + d] = min(into[c + d], bins[b, c + d])
                into[c + 3 + d] = max(into[c + 3 + d], bins[b, c + 3 + d])


@compiled.njit(nogil=True)
def _choose(level, jobs, first_job, axis, scale, mid, counts, bins, cut, left_at, right_at, children):
    """Each SAH range's plane (cut: its last bin on the left) and its
    children's bounds (children[k, slot]: box, then centres' box), and where
    each slice's spheres go: left_at[j], right_at[j]. Returns the split points."""
    inf = np.float32(np.inf)
    counts3 = np.zeros((3, BINS), np.int64)
    bins3 = np.empty((3, BINS, 12), np.float32)
    scale3 = np.zeros(3, np.float32)
    left_area = np.empty(BINS, np.float32)
    left_count = np.empty(BINS, np.int64)
    m = np.empty(level.shape[0], np.int64)
    for k in range(level.shape[0]):
        s, e = level[k, 1], level[k, 2]
        j0, j1 = first_job[k], first_job[k + 1]
        if mid[k] < 0:
            a = axis[k]
            _clear_bins(counts3[a], bins3[a])
            for j in range(j0, j1):
                counts3[a] += counts[j]
                for b in range(BINS):
                    _merge(bins3[a, b], bins[j, b : b + 1])
            scale3[:] = 0
            scale3[a] = scale[k]
            _cost, best, cut[k] = _best_plane(counts3, bins3, scale3, BINS, left_area, left_count)
            if best < 0:  # cannot happen (the extreme centres fall in the first and last bins); still valid
                mid[k] = s + (e - s) // 2
            else:
                for slot in range(2):
                    children[k, slot, 0:3] = inf
                    children[k, slot, 3:6] = -inf
                    children[k, slot, 6:9] = inf
                    children[k, slot, 9:12] = -inf
                _merge(children[k, 0], bins3[a, : cut[k] + 1])
                _merge(children[k, 1], bins3[a, cut[k] + 1 :])
        for j in range(j0, j1):  # each slice's spheres that go left, for now in right_at
            n_left = 0
            if mid[k] < 0:
                for b in range(cut[k] + 1):
                    n_left += counts[j, b]
            else:
                n_left = max(0, min(jobs[j, 2], mid[k]) - jobs[j, 1])
            right_at[j] = n_left
        left = s
        for j in range(j0, j1):
            left_at[j] = left
            left += right_at[j]
        m[k] = right = left
        for j in range(j0, j1):
            n_right = (jobs[j, 2] - jobs[j, 1]) - right_at[j]
            right_at[j] = right
            right += n_right
    return m


@compiled.njit(nogil=True)
def _move_jobs(level, jobs, p, q, axis, lo, scale, mid, cut, left_at, right_at, first, step):
    """Move the slices jobs[first::step] to the other buffer, in order: each
    slice's left side from left_at[j] on, its right side from right_at[j] on."""
    last = BINS - 1
    for j in range(first, jobs.shape[0], step):
        k = jobs[j, 0]
        src, dst = (p, q) if level[k, 4] == 0 else (q, p)
        sx, sy, sz, sr, si = src
        dx, dy, dz, dr, di = dst
        a = axis[k]
        key = sx if a == 0 else (sy if a == 1 else sz)
        c, sa, kb, split = lo[k], scale[k], cut[k], mid[k]
        lt, rt = left_at[j], right_at[j]
        for i in range(jobs[j, 1], jobs[j, 2]):
            if (i < split) if split >= 0 else (min(int((key[i] - c) * sa), last) <= kb):
                t = lt
                lt += 1
            else:
                t = rt
                rt += 1
            dx[t], dy[t], dz[t], dr[t], di[t] = sx[i], sy[i], sz[i], sr[i], si[i]


@compiled.njit(nogil=True)
def _attach(level, m, mid, children, p, q, nodes, links, used, wide):
    """Store each range's two children in its row: ranges of over `wide`
    spheres get a row and go to the next level (returned with their bounds);
    the others are subtree tasks (parent row, slot, s, e, depth, buf).
    Returns (next level, its bounds, subtrees, rows used)."""
    n = level.shape[0]
    nxt = np.empty((2 * n, 5), np.int64)
    nxt_bounds = np.empty((2 * n, 12), np.float32)
    subtrees = np.empty((2 * n, 6), np.int64)
    nn = 0
    ns = 0
    for k in range(n):
        row, s, e, d, buf = level[k, 0], level[k, 1], level[k, 2], level[k, 3], level[k, 4]
        for slot in range(2):
            cs, ce = (s, m[k]) if slot == 0 else (m[k], e)
            b = children[k, slot]
            if mid[k] >= 0:  # split by count: no bins gave the bounds
                x, y, z, r, _ = q if buf == 0 else p
                _range_bounds(x, y, z, r, cs, ce, b[:6], b[6:])
            nodes[row, CHILD_BOX[slot] : CHILD_BOX[slot] + BOX_FLOATS] = b[:6]
            links[row, REF + slot] = cs
            links[row, COUNT + slot] = ce - cs
            if ce - cs > wide:
                _open_row(nodes, links, row, slot, used)
                nxt[nn, 0], nxt[nn, 1], nxt[nn, 2], nxt[nn, 3], nxt[nn, 4] = used, cs, ce, d + 1, 1 - buf
                nxt_bounds[nn] = b
                nn += 1
                used += 1
            else:
                subtrees[ns, 0], subtrees[ns, 1], subtrees[ns, 2] = row, slot, cs
                subtrees[ns, 3], subtrees[ns, 4], subtrees[ns, 5] = ce, d, 1 - buf
                ns += 1
    return nxt[:nn], nxt_bounds[:nn], subtrees[:ns], used


@compiled.njit(nogil=True)
def _grow_subtrees(p, q, r, nodes, links, tasks, base, ends, depths, ordered, first, step):
    """Build the subtrees tasks[first::step], each into its block of rows
    from base + its first sphere, after bringing its spheres back to the
    builder's arrays where they lie in the spare ones; then their spheres'
    columns of ordered (the scene's radii r, not the padded ones)."""
    px, py, pz, pr, idx = p
    stack = _stack()
    for t in range(first, tasks.shape[0], step):
        parent, slot, s, e, d, buf = tasks[t, 0], tasks[t, 1], tasks[t, 2], tasks[t, 3], tasks[t, 4], tasks[t, 5]
        if buf == 1:
            qx, qy, qz, qr, qi = q
            for i in range(s, e):
                px[i], py[i], pz[i], pr[i], idx[i] = qx[i], qy[i], qz[i], qr[i], qi[i]
        _push(stack, 0, parent, slot, s, e, d)
        ends[t], depths[t] = _grow(px, py, pz, pr, idx, nodes, links, stack, 1, base + s)
        for i in range(s, e):
            ordered[0, i], ordered[1, i], ordered[2, i], ordered[3, i] = px[i], py[i], pz[i], r[idx[i]]


@compiled.njit(nogil=True)
def _prepare_slices(cx, cy, cz, r, p, piece, bounds, first, step):
    """_prepare the j-th slice of piece spheres into bounds[j], for j in first::step."""
    n = cx.shape[0]
    for j in range(first, bounds.shape[0], step):
        a = j * piece
        _prepare(cx, cy, cz, r, p, a, min(a + piece, n), bounds[j])


@compiled.njit(nogil=True)
def _pack(nodes, links, tasks, base, ends, starts, packed, packed_links, first, step):
    """Copy the subtrees' blocks of rows, tasks[first::step], to packed from
    starts[t] on, their inner links moved with them, and point each block's
    parent at its new place (the top's rows are already copied)."""
    for t in range(first, tasks.shape[0], step):
        parent, slot, old = tasks[t, 0], tasks[t, 1], base + tasks[t, 2]
        new = starts[t]
        for row in range(old, ends[t]):
            to = new + row - old
            packed[to] = nodes[row]
            for c in range(2):
                if packed_links[to, COUNT + c] == INNER:
                    packed_links[to, REF + c] += new - old
        if packed_links[parent, COUNT + slot] == INNER:
            packed_links[parent, REF + slot] = new


# One parallel region per step, each thread taking every parts-th job. Numba's
# threads, not a Python pool: with a pool, each thread's call unboxed its
# twenty-odd arguments while holding the GIL, one thread after another
# (docs/gpu-build.md#the-build-on-every-thread-kept).
@compiled.njit(nogil=True, parallel=True)
def _prepare_all(cx, cy, cz, r, p, piece, bounds, parts):
    for w in numba.prange(parts):
        _prepare_slices(cx, cy, cz, r, p, piece, bounds, w, parts)


@compiled.njit(nogil=True, parallel=True)
def _bin_all(level, jobs, p, q, axis, lo, scale, mid, counts, bins, parts):
    for w in numba.prange(parts):
        _bin_jobs(level, jobs, p, q, axis, lo, scale, mid, counts, bins, w, parts)


@compiled.njit(nogil=True, parallel=True)
def _move_all(level, jobs, p, q, axis, lo, scale, mid, cut, left_at, right_at, parts):
    for w in numba.prange(parts):
        _move_jobs(level, jobs, p, q, axis, lo, scale, mid, cut, left_at, right_at, w, parts)


@compiled.njit(nogil=True, parallel=True)
def _grow_all(p, q, r, nodes, links, tasks, base, ends, depths, ordered, parts):
    for w in numba.prange(parts):
        _grow_subtrees(p, q, r, nodes, links, tasks, base, ends, depths, ordered, w, parts)


@compiled.njit(nogil=True, parallel=True)
def _pack_all(nodes, links, tasks, base, ends, starts, packed, packed_links, parts):
    for w in numba.prange(parts):
        _pack(nodes, links, tasks, base, ends, starts, packed, packed_links, w, parts)


def compile_builder(wide: bool = True) -> None:
    """Compile (or load from Numba's cache) the builder's one-thread way and,
    if `wide`, its way for more than WIDE spheres, so build times leave it out.
    The wide way's parallel regions are most of the builder's compile (about
    four fifths, docs/startup.md#the-builder-compiled-only-where-a-scene-needs-it-lease-y1):
    a small scene does not pay for them."""
    spheres = np.ones((7, 9), np.float32)
    spheres[:3] = np.arange(27, dtype=np.float32).reshape(3, 9) % 5
    build(spheres, threads=1, _timed=False)
    compiled.mark_ready(oneshot.READY)
    if wide:
        build(spheres, threads=1, _timed=False, _wide=2)


def _build_narrow(code, cx, cy, cz, r):
    """The one-thread way's tree: (nodes, ordered, order, depth). code: this
    module, or compiled.as_python(this module) to run it uncompiled."""
    n = cx.shape[0]
    p = tuple(np.empty(n, np.float32) for _ in range(4)) + (np.empty(n, np.int32),)
    # IEEE arithmetic, as compiled code's: no NumPy warnings on inf or nan when uncompiled
    with np.errstate(all="ignore"):
        code._prepare(cx, cy, cz, r, p, 0, n, np.empty(12, np.float32))
        px, py, pz, pr, order = p
        nodes = np.empty((2 * max(n, 1), NODE_FLOATS), np.float32)
        stack = code._stack()
        links = nodes.view(np.int32)
        top = code._root(px, py, pz, pr, order, nodes, links, stack)
        used, depth = code._grow(px, py, pz, pr, order, nodes, links, stack, top, 1)
    # the centres are already in leaf order (the builder moved them), the very values of the scene
    return nodes[:used].copy(), np.stack([px, py, pz, r[order]]), order, depth


def _piece(spheres: int, threads: int) -> int:
    """Spheres per slice of a level of wide ranges: a few slices per thread."""
    return min(SLICE, max(1024, spheres // (4 * threads)))


def _build_wide(cx, cy, cz, r, threads: int, wide: int):
    """The tree of n > wide spheres (centres cx, cy, cz, radii r): its top
    level by level, each range of over `wide` spheres split by all threads,
    then the subtrees below on one thread each, each into its own block of
    rows, then the blocks packed after the top's rows. Returns (nodes,
    ordered, order, deepest depth)."""
    n = cx.shape[0]
    p = (
        np.empty(n, np.float32),
        np.empty(n, np.float32),
        np.empty(n, np.float32),
        np.empty(n, np.float32),
        np.empty(n, np.int32),
    )
    q = tuple(np.empty_like(a) for a in p)
    # the top's rows, then one block per subtree at the top's row count plus
    # its first sphere: a subtree of k spheres has fewer than k inner nodes
    nodes = np.empty((2 * n, NODE_FLOATS), np.float32)
    links = nodes.view(np.int32)
    ordered = np.empty((4, n), np.float32)
    piece = _piece(n, threads)
    parts = np.empty(((n + piece - 1) // piece, 12), np.float32)
    _prepare_all(cx, cy, cz, r, p, piece, parts, threads)
    _empty_children(nodes, 0)
    level = np.array([[0, 0, n, 1, 0]], np.int64)  # row, s, e, the row's depth, buf
    bounds = parts[:1].copy()  # the slices' bounds merged: the root's
    _merge(bounds[0], parts)
    used, depth, subtrees = 1, 1, []
    while len(level):
        k = len(level)
        axis, lo, scale = np.empty(k, np.int64), np.empty(k, np.float32), np.empty(k, np.float32)
        mid, first_job, cut = np.empty(k, np.int64), np.empty(k + 1, np.int64), np.zeros(k, np.int64)
        jobs = _plan(
            level,
            bounds,
            p,
            q,
            _piece(int((level[:, 2] - level[:, 1]).sum()), threads),
            axis,
            lo,
            scale,
            mid,
            first_job,
        )
        counts, bins = np.empty((len(jobs), BINS), np.int64), np.empty((len(jobs), BINS, 12), np.float32)
        _bin_all(level, jobs, p, q, axis, lo, scale, mid, counts, bins, threads)
        left_at, right_at = np.empty(len(jobs), np.int64), np.empty(len(jobs), np.int64)
        children = np.empty((k, 2, 12), np.float32)
        m = _choose(level, jobs, first_job, axis, scale, mid, counts, bins, cut, left_at, right_at, children)
        _move_all(level, jobs, p, q, axis, lo, scale, mid, cut, left_at, right_at, threads)
        depth = max(depth, int(level[:, 3].max()))
        level, bounds, below, used = _attach(level, m, mid, children, p, q, nodes, links, used, wide)
        subtrees.append(below)
    tasks = np.concatenate(subtrees)
    tasks = tasks[np.argsort(tasks[:, 2] - tasks[:, 3], kind="stable")]  # largest first
    ends, depths = np.empty(len(tasks), np.int64), np.empty(len(tasks), np.int64)
    # subtrees differ in cost: more parts than threads, handed out one at a time as threads come free
    chunk = numba.set_parallel_chunksize(1)
    try:
        _grow_all(p, q, r, nodes, links, tasks, used, ends, depths, ordered, 4 * threads)
    finally:
        numba.set_parallel_chunksize(chunk)
    sizes = ends - (used + tasks[:, 2])
    starts = used + np.cumsum(sizes) - sizes
    packed = np.empty((used + int(sizes.sum()), NODE_FLOATS), np.float32)
    packed[:used] = nodes[:used]
    _pack_all(nodes, links, tasks, used, ends, starts, packed, packed.view(np.int32), threads)
    return packed, ordered, p[4], max(depth, int(depths.max()))


def build(
    spheres: np.ndarray, threads: int | None = None, device: str = "cpu", _timed: bool = True, _wide: int = WIDE
) -> Bvh:
    """The BVH of a (7, N) float32 sphere array (Scene.spheres), built on
    `threads` threads (default: all cores). Up to `_wide` spheres, on one
    thread; above, the top of the tree is split by all threads together, the
    subtrees below on one thread each. The tree is the same on any number of
    threads. device: the one whose walks the tree is for ("cpu", "cuda",
    "wgpu"). Within oneshot.one_shot(), a scene of up to `_wide` spheres may be built
    by the builder's uncompiled Python, the same tree (Bvh.interpreted)."""
    n = spheres.shape[1]
    if n > MAX_SPHERES:
        raise RaybenchError(f"bvh: at most {MAX_SPHERES:,} spheres, got {n:,}")
    threads = threads or usable_cores()
    interpret, elsewhere = oneshot.in_python(n, _wide, device) if _timed else (False, False)
    oneshot.note_build(interpret)
    if elsewhere:
        oneshot.compile_elsewhere()
    elif _timed and not interpret:
        compile_builder(wide=n > _wide)
    cx, cy, cz, r = (np.ascontiguousarray(spheres[k]) for k in range(4))
    start = time.perf_counter()
    if n > _wide:
        # Numba's threads are at most its pool's (the cores); the slicing into
        # parts follows `threads` all the same. Its default threading layer
        # cannot run two parallel regions at once: one build at a time.
        with _ONE_BUILD:
            before = numba.get_num_threads()
            numba.set_num_threads(min(threads, numba.config.NUMBA_NUM_THREADS))
            try:
                nodes, ordered, order, depth = _build_wide(cx, cy, cz, r, threads, _wide)
            finally:
                numba.set_num_threads(before)
    else:
        code = compiled.as_python(sys.modules[__name__]) if interpret else sys.modules[__name__]
        nodes, ordered, order, depth = _build_narrow(code, cx, cy, cz, r)
    build_s = time.perf_counter() - start
    return Bvh(
        nodes=nodes,
        links=nodes.view(np.int32),
        ordered=ordered,
        order=order,
        depth=int(depth),
        build_s=build_s,
        interpreted=interpret,
    )
