"""The bounding volume hierarchy over the spheres: its builder and its layout.

Builder: top-down binned SAH (surface area heuristic), compiled with Numba.
An LBVH (Morton codes) builds faster on a GPU, but its splits fall at fixed
spatial midpoints whatever the spheres do, and for the benchmark's scenes
(spheres bunched in a view frustum, radii shrinking with the count) that gives
trees a ray walks more nodes of. Binned SAH picks, at every node, the split of
16 candidate planes per axis that minimises the expected cost of a random ray,
in O(n) per level; 1,000,000 spheres build well under the issue's 1 s on two
cores, and the trace, done every frame, is what the tree must serve.

Layout, shared by every backend (they get the same arrays):
  nodes  (M, 16) float32, one 64-byte row per node, one cache line: the boxes
         of BOTH children (lo xyz, hi xyz of child 0, then of child 1), so one
         row fetch tests two boxes; columns 12..15 hold int32 (the `links`
         view of the same memory): the children's refs and counts.
           count == INNER: ref is the child node's row;
           count >= 0:     a leaf of `count` spheres from `ref` in `ordered`
                           (0: an empty child, whose box is inverted: lo EMPTY, hi -EMPTY).
  ordered (4, N) float32: centre and radius of the spheres in leaf order,
         the very float32 values of the scene, so the exact test's arithmetic
         is the brute-force path's.
  order  (N,) int32: the original index of each ordered sphere; hits report it.
Node 0 is the root. Every box is the union of its spheres' boxes, each sphere's
box padded by PAD (see sphere_pad) so a box never excludes a hit the exact
float32 test reports.

Depth is bounded by MAX_DEPTH whatever the input: where SAH splits would go
deeper, the builder splits by count (object median), and spheres whose centres
all coincide are split by count too.
"""

from __future__ import annotations

import os
import time
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass

import numba
import numpy as np

from .errors import RaybenchError

INNER = -1
BINS = 16
LEAF_MAX = 8
# Leaves of up to LEAF_ALWAYS spheres are kept without weighing a split:
# the split would seldom win (a node visit costs about NODE_COST sphere
# tests) and weighing it is most of the build's time at the bottom of the tree.
LEAF_ALWAYS = 3
# Expected cost of visiting a node (two box tests), in sphere tests; the SAH
# weighs splitting against leaving the spheres in one leaf with it.
NODE_COST = np.float32(2.0)
MAX_DEPTH = 48
# Ranges of more spheres are binned along the centres' widest axis only
# (Wald 2007): a third of the work where the build spends most of it, for
# trees the walk measures no slower on the benchmark's scenes.
ONE_AXIS_ABOVE = 4096
# Traversal stack entries: one per level on the way down is the most a
# near-first walk keeps (each level pushes at most its far child).
STACK = MAX_DEPTH + 2
NODE_FLOATS = 16
NODE_BYTES = NODE_FLOATS * 4
# Bytes the builder holds per sphere at its peak: work arrays, ordered
# spheres and order, a deferred task, two rows of nodes and the packed copy.
BUILD_SPHERE_BYTES = 5 * 4 + 5 * 4 + 5 * 8 + 3 * NODE_BYTES + 8
# Per sphere on the device after the build: nodes (at most one per sphere),
# ordered spheres, order.
DEVICE_SPHERE_BYTES = NODE_BYTES + 4 * 4 + 4
# Relative padding of every sphere's box, of (radius + |centre|_1); the
# traversal adds the same fraction of |camera|_1 (kernels.traverse). 2^-16 is
# 128 float32 epsilons: many times the few epsilons by which the exact test's
# float32 hit point can stray from the true sphere (|EO| and r scale them).
PAD = np.float32(2.0 ** -16)
# The planes of an empty child's inverted box (only a root of under two
# spheres has one): far beyond any scene (coordinates stay under 1e15), and
# finite even divided by a direction component of TINY (kernels.traverse),
# so no walk's arithmetic on it overflows or meets inf - inf.
EMPTY = np.float32(1e18)
MAX_SPHERES = 2 ** 31 - 1


@dataclass
class Bvh:
    nodes: np.ndarray      # (M, 16) float32
    links: np.ndarray      # (M, 16) int32 view of nodes; columns 12..15 used
    ordered: np.ndarray    # (4, N) float32: cx, cy, cz, r in leaf order
    order: np.ndarray      # (N,) int32: original index of each ordered sphere
    depth: int             # deepest node (root = 1)
    build_s: float         # seconds the build took (compiled code only)

    @property
    def count(self) -> int:
        return self.order.shape[0]

    @property
    def node_count(self) -> int:
        return self.nodes.shape[0]


def sphere_pad(cx, cy, cz, r):
    """The padding of one sphere's box, as the builder computes it."""
    return (r + (abs(cx) + abs(cy) + abs(cz))) * PAD


@numba.njit(nogil=True, cache=True)
def _log2ceil(n):
    k = 0
    while (1 << k) < n:
        k += 1
    return k


@numba.njit(nogil=True, cache=True)
def _range_bounds(px, py, pz, pr, s, e, box, cbox):
    """box: union of the spheres' padded boxes over [s, e); cbox: bounds of their centres."""
    inf = np.float32(np.inf)
    for a in range(3):
        box[a] = inf
        box[3 + a] = -inf
        cbox[a] = inf
        cbox[3 + a] = -inf
    for i in range(s, e):
        x, y, z, r = px[i], py[i], pz[i], pr[i]
        box[0] = min(box[0], x - r)
        box[1] = min(box[1], y - r)
        box[2] = min(box[2], z - r)
        box[3] = max(box[3], x + r)
        box[4] = max(box[4], y + r)
        box[5] = max(box[5], z + r)
        cbox[0] = min(cbox[0], x)
        cbox[1] = min(cbox[1], y)
        cbox[2] = min(cbox[2], z)
        cbox[3] = max(cbox[3], x)
        cbox[4] = max(cbox[4], y)
        cbox[5] = max(cbox[5], z)


@numba.njit(nogil=True, cache=True)
def _area(lx, ly, lz, hx, hy, hz):
    dx, dy, dz = hx - lx, hy - ly, hz - lz
    return dx * dy + dy * dz + dz * dx


@numba.njit(nogil=True, cache=True)
def _swap(px, py, pz, pr, idx, i, j):
    px[i], px[j] = px[j], px[i]
    py[i], py[j] = py[j], py[i]
    pz[i], pz[j] = pz[j], pz[i]
    pr[i], pr[j] = pr[j], pr[i]
    idx[i], idx[j] = idx[j], idx[i]


@numba.njit(nogil=True, cache=True)
def _median_split(px, py, pz, pr, idx, s, e, cbox):
    """Split [s, e) in two halves by count, ordered along the centres' widest axis."""
    ext0, ext1, ext2 = cbox[3] - cbox[0], cbox[4] - cbox[1], cbox[5] - cbox[2]
    axis = 0 if ext0 >= ext1 and ext0 >= ext2 else (1 if ext1 >= ext2 else 2)
    if max(ext0, max(ext1, ext2)) > 0:
        key = (px if axis == 0 else (py if axis == 1 else pz))[s:e]
        perm = np.argsort(key, kind="mergesort") + s
        tx, ty, tz, tr, ti = px[perm], py[perm], pz[perm], pr[perm], idx[perm]
        px[s:e], py[s:e], pz[s:e], pr[s:e], idx[s:e] = tx, ty, tz, tr, ti
    return s + (e - s) // 2


@numba.njit(nogil=True, cache=True)
def _sah_split(px, py, pz, pr, idx, s, e, box, cbox, counts, bins, scale, left_area, left_count):
    """Binned SAH: the best of nb-1 planes on each axis (nb = BINS, fewer
    for a few spheres). Returns the split point m (s < m < e) and the
    split's cost relative to the node's area (inf if the centres coincide:
    no plane separates them). counts to left_count: scratch arrays."""
    inf = np.float32(np.inf)
    best_cost = inf
    best_axis = -1
    best_bin = 0
    nb = min(BINS, max(4, e - s))
    for a in range(3):
        ext = cbox[3 + a] - cbox[a]
        scale[a] = np.float32(nb * (1 - 1e-5)) / ext if ext > 0 else np.float32(0.0)
    if e - s > ONE_AXIS_ABOVE:  # only the widest axis of the centres
        wide = 0
        for a in range(1, 3):
            if cbox[3 + a] - cbox[a] > cbox[3 + wide] - cbox[wide]:
                wide = a
        for a in range(3):
            if a != wide:
                scale[a] = np.float32(0.0)
    counts[:, :nb] = 0
    for a in range(3):
        for k in range(nb):
            bins[a, k, 0] = inf
            bins[a, k, 1] = inf
            bins[a, k, 2] = inf
            bins[a, k, 3] = -inf
            bins[a, k, 4] = -inf
            bins[a, k, 5] = -inf
    c0, c1, c2 = cbox[0], cbox[1], cbox[2]
    s0, s1, s2 = scale[0], scale[1], scale[2]
    last = nb - 1
    if e - s > ONE_AXIS_ABOVE:
        a = wide
        c = c0 if a == 0 else (c1 if a == 1 else c2)
        sa = scale[a]
        key = px if a == 0 else (py if a == 1 else pz)
        for i in range(s, e):
            x, y, z, r = px[i], py[i], pz[i], pr[i]
            k = min(int((key[i] - c) * sa), last)
            counts[a, k] += 1
            bins[a, k, 0] = min(bins[a, k, 0], x - r)
            bins[a, k, 1] = min(bins[a, k, 1], y - r)
            bins[a, k, 2] = min(bins[a, k, 2], z - r)
            bins[a, k, 3] = max(bins[a, k, 3], x + r)
            bins[a, k, 4] = max(bins[a, k, 4], y + r)
            bins[a, k, 5] = max(bins[a, k, 5], z + r)
    # the three axes written out: the hot loop of the build
    for i in range(s if e - s <= ONE_AXIS_ABOVE else e, e):
        x, y, z, r = px[i], py[i], pz[i], pr[i]
        lx, ly, lz, hx, hy, hz = x - r, y - r, z - r, x + r, y + r, z + r
        k = min(int((x - c0) * s0), last)
        counts[0, k] += 1
        bins[0, k, 0] = min(bins[0, k, 0], lx)
        bins[0, k, 1] = min(bins[0, k, 1], ly)
        bins[0, k, 2] = min(bins[0, k, 2], lz)
        bins[0, k, 3] = max(bins[0, k, 3], hx)
        bins[0, k, 4] = max(bins[0, k, 4], hy)
        bins[0, k, 5] = max(bins[0, k, 5], hz)
        k = min(int((y - c1) * s1), last)
        counts[1, k] += 1
        bins[1, k, 0] = min(bins[1, k, 0], lx)
        bins[1, k, 1] = min(bins[1, k, 1], ly)
        bins[1, k, 2] = min(bins[1, k, 2], lz)
        bins[1, k, 3] = max(bins[1, k, 3], hx)
        bins[1, k, 4] = max(bins[1, k, 4], hy)
        bins[1, k, 5] = max(bins[1, k, 5], hz)
        k = min(int((z - c2) * s2), last)
        counts[2, k] += 1
        bins[2, k, 0] = min(bins[2, k, 0], lx)
        bins[2, k, 1] = min(bins[2, k, 1], ly)
        bins[2, k, 2] = min(bins[2, k, 2], lz)
        bins[2, k, 3] = max(bins[2, k, 3], hx)
        bins[2, k, 4] = max(bins[2, k, 4], hy)
        bins[2, k, 5] = max(bins[2, k, 5], hz)
    for a in range(3):
        if scale[a] == 0:
            continue
        lx = ly = lz = inf
        hx = hy = hz = -inf
        n = 0
        for k in range(nb - 1):
            b = bins[a, k]
            lx, ly, lz = min(lx, b[0]), min(ly, b[1]), min(lz, b[2])
            hx, hy, hz = max(hx, b[3]), max(hy, b[4]), max(hz, b[5])
            n += counts[a, k]
            left_area[k] = _area(lx, ly, lz, hx, hy, hz) if n > 0 else np.float32(0.0)
            left_count[k] = n
        lx = ly = lz = inf
        hx = hy = hz = -inf
        n = 0
        for k in range(nb - 1, 0, -1):
            b = bins[a, k]
            lx, ly, lz = min(lx, b[0]), min(ly, b[1]), min(lz, b[2])
            hx, hy, hz = max(hx, b[3]), max(hy, b[4]), max(hz, b[5])
            n += counts[a, k]
            nl = left_count[k - 1]
            if n == 0 or nl == 0:
                continue
            cost = np.float32(nl) * left_area[k - 1] + np.float32(n) * _area(lx, ly, lz, hx, hy, hz)
            if cost < best_cost:
                best_cost, best_axis, best_bin = cost, a, k - 1
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


@numba.njit(nogil=True, cache=True)
def _push(stack, top, parent, slot, s, e, d):
    stack[top, 0] = parent
    stack[top, 1] = slot
    stack[top, 2] = s
    stack[top, 3] = e
    stack[top, 4] = d
    return top + 1


@numba.njit(nogil=True, cache=True)
def _root(px, py, pz, pr, idx, nodes, links, stack):
    """Row 0, the root, with its spheres split in two children whatever their
    number; pushes their tasks (parent row, slot, start, end, parent's depth)
    on stack and returns the stack's height."""
    n = px.shape[0]
    box = np.empty(6, np.float32)
    cbox = np.empty(6, np.float32)
    nodes[0, :12] = EMPTY
    for slot in range(2):
        nodes[0, 6 * slot + 3: 6 * slot + 6] = -EMPTY
        links[0, 12 + slot] = 0
        links[0, 14 + slot] = 0
    if n == 0:
        return 0
    _range_bounds(px, py, pz, pr, 0, n, box, cbox)
    if n == 1:
        m = 1
    elif 1 + _log2ceil(n) >= MAX_DEPTH:
        m = _median_split(px, py, pz, pr, idx, 0, n, cbox)
    else:
        m, _cost = _sah_split(px, py, pz, pr, idx, 0, n, box, cbox, np.zeros((3, BINS), np.int64),
                              np.empty((3, BINS, 6), np.float32), np.empty(3, np.float32),
                              np.empty(BINS, np.float32), np.empty(BINS, np.int64))
        if m == 0 or m == n:
            m = _median_split(px, py, pz, pr, idx, 0, n, cbox)
    top = _push(stack, 0, 0, 1, m, n, 1)
    return _push(stack, top, 0, 0, 0, m, 1)


@numba.njit(nogil=True, cache=True)
def _grow(px, py, pz, pr, idx, nodes, links, stack, top, used, cutoff, deferred):
    """Build the subtrees of the tasks on stack, new rows from `used` on.
    Tasks of at most `cutoff` spheres (cutoff > 0) are not built but moved to
    `deferred`, for threads to build apart. Returns (rows used, deepest
    depth, tasks deferred)."""
    inf = np.float32(np.inf)
    box = np.empty(6, np.float32)
    cbox = np.empty(6, np.float32)
    counts = np.zeros((3, BINS), np.int64)
    bins = np.empty((3, BINS, 6), np.float32)
    scale = np.empty(3, np.float32)
    left_area = np.empty(BINS, np.float32)
    left_count = np.empty(BINS, np.int64)
    depth = 1
    waiting = 0
    while top > 0:
        top -= 1
        parent, slot, s, e, d = stack[top, 0], stack[top, 1], stack[top, 2], stack[top, 3], stack[top, 4]
        count = e - s
        if count > 1 and count <= cutoff:
            deferred[waiting, :] = stack[top, :]
            waiting += 1
            continue
        col = 6 * slot
        links[parent, 12 + slot] = s
        links[parent, 14 + slot] = count
        depth = max(depth, d)
        if count == 0:
            continue  # an empty child: its box stays inverted
        _range_bounds(px, py, pz, pr, s, e, box, cbox)
        nodes[parent, col: col + 6] = box
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
        links[parent, 12 + slot] = row
        links[parent, 14 + slot] = INNER
        nodes[row, :12] = EMPTY
        nodes[row, 3:6] = -EMPTY
        nodes[row, 9:12] = -EMPTY
        top = _push(stack, top, row, 1, m, e, d + 1)
        top = _push(stack, top, row, 0, s, m, d + 1)
    return used, depth, waiting


def _stack():
    return np.empty((2 * MAX_DEPTH + 8, 5), np.int64)


def memory_bytes(n: int) -> int:
    """Host bytes a build of n spheres holds at its peak."""
    return max(n, 1) * BUILD_SPHERE_BYTES


def compile_builder() -> None:
    """Compile (or load from Numba's cache) the builder, so build times leave it out."""
    build(np.ones((7, 3), np.float32), threads=1, _timed=False)


def build(spheres: np.ndarray, threads: int | None = None, _timed: bool = True) -> Bvh:
    """The BVH of a (7, N) float32 sphere array (Scene.spheres), built on
    `threads` threads (default: all cores): the top of the tree on one, then
    its subtrees side by side, each into its own block of rows, then the rows
    packed together."""
    n = spheres.shape[1]
    if n > MAX_SPHERES:
        raise RaybenchError(f"bvh: at most {MAX_SPHERES:,} spheres, got {n:,}")
    threads = threads or os.cpu_count() or 1
    if _timed:
        compile_builder()
    cx, cy, cz, r = (np.ascontiguousarray(spheres[k]) for k in range(4))
    start = time.perf_counter()
    px, py, pz = cx.copy(), cy.copy(), cz.copy()
    pr = r + sphere_pad(cx, cy, cz, r)
    idx = np.arange(n, dtype=np.int32)
    # the top's rows, then one block per subtree at the top's row count plus
    # its first sphere: a subtree of k spheres has fewer than k inner nodes
    nodes = np.empty((2 * max(n, 1), NODE_FLOATS), np.float32)
    links = nodes.view(np.int32)
    stack = _stack()
    top = _root(px, py, pz, pr, idx, nodes, links, stack)
    cutoff = n // (8 * threads) if threads > 1 and n >= 4096 else 0
    deferred = np.empty((max(n, 1), 5), np.int64) if cutoff else np.empty((1, 5), np.int64)
    used, depth, waiting = _grow(px, py, pz, pr, idx, nodes, links, stack, top, 1, cutoff, deferred)
    rows = [np.arange(used)]
    if waiting:
        tasks = sorted(deferred[:waiting].tolist(), key=lambda t: t[2] - t[3])  # largest first

        def one(task):
            st = _stack()
            st[0] = task
            return _grow(px, py, pz, pr, idx, nodes, links, st, 1, used + task[2], 0, deferred[:1])

        with ThreadPoolExecutor(threads) as pool:
            done = list(pool.map(one, tasks))
        for task, (end, d, _) in zip(tasks, done):
            depth = max(depth, d)
            rows.append(np.arange(used + task[2], end))
    rows = np.concatenate(rows)
    nodes = nodes[rows]
    if waiting:  # rows moved: point the inner links at their new places
        place = np.full(used + n, -1, np.int64)
        place[rows] = np.arange(len(rows))
        links = nodes.view(np.int32)
        for slot in range(2):
            inner = links[:, 14 + slot] == INNER
            links[inner, 12 + slot] = place[links[inner, 12 + slot]]
    # the centres are already in leaf order (the builder moved them), the very values of the scene
    ordered = np.stack([px, py, pz, r[idx]]) if n else np.zeros((4, 0), np.float32)
    build_s = time.perf_counter() - start
    return Bvh(nodes=nodes, links=nodes.view(np.int32), ordered=np.ascontiguousarray(ordered, np.float32),
               order=idx, depth=int(depth), build_s=build_s)
