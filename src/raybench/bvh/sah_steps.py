"""The host builder's steps on one range of primitives, compiled with Numba:
the binned SAH split of a range (or by count where SAH would go too deep),
and the subtree grown below it on one thread (bvh/sah.py puts them together,
bvh/sah_wide.py splits the top of a large tree with every thread).

The builder sees a primitive only through its extent (its padded box as a
centre and half sizes) and copy_leaf (its row of the tree's leaf buffer),
both the primitive module's own (kernels/primitives). Its work arrays p are
(x, y, z, h, idx): each primitive's box centre, the largest of its half
sizes and its index in the scene, moved together as the ranges are split.
One half size, not three: a sphere's box is a cube, and two more arrays to
bin and move slowed every build
(docs/notes/gpu-build.md#the-host-builder-on-a-primitives-extent). A
primitive whose box is not a cube has its splits weighed over the cube
around it, and then (bvh/sah.py) the tree's boxes refitted to its own
padded boxes (_refit, through the primitive's bounds): the boxes a walk
tests are tight, and splits weighed over the real boxes made trees of
about the same cost, slower to build."""

from __future__ import annotations

import functools

import numba
import numpy as np

from .. import compiled
from ..kernels.primitives import sphere
from ..layout import (
    BOX_FLOATS,
    CHILD_BOX,
    COUNT,
    EMPTY,
    INNER,
    MAX_DEPTH,
    REF,
)

BINS = 16
LEAF_MAX = 8
# Leaves of up to LEAF_ALWAYS spheres are kept without weighing a split:
# the split would seldom win (a node visit costs about NODE_COST sphere
# tests) and weighing it is most of the build's time at the bottom of the tree.
LEAF_ALWAYS = 3
# Ranges of more spheres than WIDE are split by all the build's threads at
# once, each binning and then moving a slice of at most SLICE spheres, so the
# top of a large tree does not wait on one core (_grow_wide); smaller ones are
# whole subtrees, one thread each. WIDE is a count, not a share of the threads,
# so the tree is the same on any number of threads. Wide ranges are binned
# along their centres' widest axis only (Wald 2007): a third of the work where
# the build spends most of it, for trees the walk measures no slower on the
# benchmark's scenes.
WIDE = 4096


# The primitive's answers to the builder, compiled into its steps (module
# globals, which is how compiled code sees them): the sphere's at import;
# compiled.rebound compiles the steps again for another kind (bvh/sah.py).
@functools.cache
def _made(primitive=sphere):
    """The answers of one kind of primitive, compiled to be inlined into the steps."""
    return primitive.make(numba.njit(inline="always"))


_primitive = _made()
_extent, _copy_leaf, _bounds = _primitive.extent, _primitive.copy_leaf, _primitive.bounds


def work_arrays(n):
    """The builder's arrays p for n primitives: (x, y, z, h, idx)."""
    return tuple(np.empty(n, np.float32) for _ in range(4)) + (np.empty(n, np.int32),)


@compiled.njit(nogil=True)
def _prepare(items, p, s, e, bounds):
    """The builder's arrays p for the primitives [s, e) of the scene's buffer
    `items`: their extents and indices; bounds (12,): their box, then their
    centres' box."""
    px, py, pz, ph, idx = p
    for i in range(s, e):
        px[i], py[i], pz[i], hx, hy, hz = _extent(items, i)
        ph[i] = max(hx, max(hy, hz))
        idx[i] = i
    _range_bounds(p, s, e, bounds[:6], bounds[6:])


@compiled.njit(nogil=True)
def _leaves(items, idx, s, e, leaves):
    """The tree's leaf buffer's columns [s, e): the primitives idx[s:e] of items, in that order."""
    for i in range(s, e):
        _copy_leaf(items, idx[i], leaves, i)


@compiled.njit(nogil=True)
def _refit(nodes, links, leaves):
    """Every child box of the tree (nodes, links) made again from its
    leaves' own padded boxes (the primitive's bounds on the leaf buffer),
    bottom up: the boxes the steps built hold the cube around each
    primitive's box, which for a primitive whose box is no cube is looser
    than the box, so rays would enter more nodes than they need. The
    builders number a row's inner children after it, so rows in reverse
    order meet every child before its parent. Each new box is the union of
    boxes the old one holds: no hit is lost, and an empty child's box stays
    inverted."""
    inf = np.float32(np.inf)
    for row in range(nodes.shape[0] - 1, -1, -1):
        for slot in range(2):
            ref, count = links[row, REF + slot], links[row, COUNT + slot]
            if count == 0:
                continue
            lx = ly = lz = inf
            hx = hy = hz = -inf
            if count == INNER:
                for c in CHILD_BOX:
                    lx, ly, lz = min(lx, nodes[ref, c]), min(ly, nodes[ref, c + 1]), min(lz, nodes[ref, c + 2])
                    hx, hy, hz = max(hx, nodes[ref, c + 3]), max(hy, nodes[ref, c + 4]), max(hz, nodes[ref, c + 5])
            else:
                for k in range(ref, ref + count):
                    bx0, by0, bz0, bx1, by1, bz1 = _bounds(leaves, k)
                    lx, ly, lz = min(lx, bx0), min(ly, by0), min(lz, bz0)
                    hx, hy, hz = max(hx, bx1), max(hy, by1), max(hz, bz1)
            col = CHILD_BOX[slot]
            nodes[row, col], nodes[row, col + 1], nodes[row, col + 2] = lx, ly, lz
            nodes[row, col + 3], nodes[row, col + 4], nodes[row, col + 5] = hx, hy, hz


@compiled.njit(nogil=True)
def _log2ceil(n):
    k = 0
    while (1 << k) < n:
        k += 1
    return k


@compiled.njit(nogil=True)
def _range_bounds(p, s, e, box, cbox):
    """box: union of the primitives' boxes over [s, e); cbox: bounds of their centres."""
    px, py, pz, ph, _ = p
    # in locals, not box[]: stores to an array that may alias px cannot stay in
    # registers (docs/notes/gpu-build.md#figures-moved-from-the-sources-comments)
    inf = np.float32(np.inf)
    lx = ly = lz = clx = cly = clz = inf
    hx = hy = hz = chx = chy = chz = -inf
    for i in range(s, e):
        x, y, z, h = px[i], py[i], pz[i], ph[i]
        lx, ly, lz = min(lx, x - h), min(ly, y - h), min(lz, z - h)
        hx, hy, hz = max(hx, x + h), max(hy, y + h), max(hz, z + h)
        clx, cly, clz = min(clx, x), min(cly, y), min(clz, z)
        chx, chy, chz = max(chx, x), max(chy, y), max(chz, z)
    box[0], box[1], box[2], box[3], box[4], box[5] = lx, ly, lz, hx, hy, hz
    cbox[0], cbox[1], cbox[2], cbox[3], cbox[4], cbox[5] = clx, cly, clz, chx, chy, chz


@compiled.njit(nogil=True)
def _area(lx, ly, lz, hx, hy, hz):
    dx, dy, dz = hx - lx, hy - ly, hz - lz
    return dx * dy + dy * dz + dz * dx


@compiled.njit(nogil=True)
def _swap(p, i, j):
    px, py, pz, ph, idx = p
    px[i], px[j] = px[j], px[i]
    py[i], py[j] = py[j], py[i]
    pz[i], pz[j] = pz[j], pz[i]
    ph[i], ph[j] = ph[j], ph[i]
    idx[i], idx[j] = idx[j], idx[i]


@compiled.njit(nogil=True)
def _median_split(p, s, e, cbox):
    """Split [s, e) in two halves by count along the centres' widest axis:
    the first half's centres no greater than the second's. A selection in
    place (Hoare's), not a sort: it compiles in a fraction of the time, and
    the order within each half does not matter to the builder."""
    ext0, ext1, ext2 = cbox[3] - cbox[0], cbox[4] - cbox[1], cbox[5] - cbox[2]
    axis = 0 if ext0 >= ext1 and ext0 >= ext2 else (1 if ext1 >= ext2 else 2)
    m = s + (e - s) // 2
    if max(ext0, max(ext1, ext2)) > 0:
        key = p[0] if axis == 0 else (p[1] if axis == 1 else p[2])
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
                    _swap(p, i, j)
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
def _sah_split(p, s, e, box, cbox, counts, bins, scale, left_area, left_count):
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
    px, py, pz, ph, _ = p
    # the three axes written out: the hot loop of the build
    for i in range(s, e):
        x, y, z, h = px[i], py[i], pz[i], ph[i]
        lx, ly, lz, hx, hy, hz = x - h, y - h, z - h, x + h, y + h, z + h
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
            _swap(p, i, j)
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
def _root(p, nodes, links, stack):
    """Row 0, the root, with its primitives split in two children whatever
    their number; pushes their tasks (parent row, slot, start, end, parent's
    depth) on stack and returns the stack's height."""
    n = p[0].shape[0]
    box = np.empty(6, np.float32)
    cbox = np.empty(6, np.float32)
    _empty_children(nodes, 0)
    for slot in range(2):
        links[0, REF + slot] = 0
        links[0, COUNT + slot] = 0
    if n == 0:
        return 0
    _range_bounds(p, 0, n, box, cbox)
    if n == 1:
        m = 1
    elif 1 + _log2ceil(n) >= MAX_DEPTH:
        m = _median_split(p, 0, n, cbox)
    else:
        m, _cost = _sah_split(
            p,
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
            m = _median_split(p, 0, n, cbox)
    top = _push(stack, 0, 0, 1, m, n, 1)
    return _push(stack, top, 0, 0, 0, m, 1)


@compiled.njit(nogil=True)
def _open_row(nodes, links, parent, slot, row):
    """Make row an inner node, the child (parent, slot), with both its children empty for now."""
    links[parent, REF + slot] = row
    links[parent, COUNT + slot] = INNER
    _empty_children(nodes, row)


@compiled.njit(nogil=True)
def _grow(p, nodes, links, stack, top, used, node_cost):
    """Build the subtrees of the tasks on stack, new rows from `used` on; a
    range of up to LEAF_MAX is left a leaf where the SAH finds no split
    cheaper, a node's visit costing node_cost primitives' tests (float32:
    NODE_COST, or the walk's own for a kind: build's node_cost). Returns
    (rows used, deepest depth)."""
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
        _range_bounds(p, s, e, box, cbox)
        for k in range(BOX_FLOATS):
            nodes[parent, col + k] = box[k]
        if count <= LEAF_ALWAYS:
            continue
        if d + 1 + _log2ceil(count) >= MAX_DEPTH:  # deeper SAH splits could overflow the stack
            m = _median_split(p, s, e, cbox)
        else:
            m, rel = _sah_split(p, s, e, box, cbox, counts, bins, scale, left_area, left_count)
            if count <= LEAF_MAX and (m == s or np.float32(count) <= node_cost + rel):
                continue  # a leaf: cheaper than the best split
            if m == s or m == e:  # the centres coincide: split by count
                m = _median_split(p, s, e, cbox)
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
