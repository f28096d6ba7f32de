"""The top of a large tree, each split shared by all the build's threads
(bvh/sah.py's build, for more than WIDE primitives): its levels split in
parallel regions, then the subtrees below grown one a thread and packed."""

from __future__ import annotations

import numba
import numpy as np

from .. import compiled
from ..layout import (
    BOX_FLOATS,
    CHILD_BOX,
    COUNT,
    INNER,
    MAX_DEPTH,
    NODE_COST,
    NODE_FLOATS,
    REF,
)
from .pages import mapped, release, reserve, scratch
from .sah_steps import (
    BINS,
    _best_plane,
    _clear_bins,
    _empty_children,
    _grow,
    _leaves,
    _log2ceil,
    _median_split,
    _open_row,
    _prepare,
    _push,
    _range_bounds,
    _stack,
    _widest,
)

# A slice of a wide range (sah_steps.WIDE says why the top is sliced): at
# most SLICE primitives, binned and moved by one thread.
SLICE = 1 << 14
# Below the top, a large tree's subtrees are grown, and then packed, in RUNS runs along the
# primitives, and each run gives back what it no longer needs as it ends: its part of the
# builder's arrays but the order, then its subtrees' rows once packed. Held whole beside the
# nodes, either was a shared-vertex mesh's peak (docs/notes/mesh-memory.md).
RUNS = 8

# --- the top of a large tree: each split shared by all threads -----------------------
#
# A level of wide ranges is split in four steps: plan (which axis, how it is
# sliced), bin the slices (threads), choose each range's plane and where each
# slice's primitives go, move them (threads), then attach the children. A
# slice's primitives are moved in order, each side to its place, one of the
# builder's five arrays at a time through one spare array, which then takes
# that array's place: a spare set of all five was most of a shared-vertex
# mesh's peak (docs/notes/mesh-memory.md). The indices move first, and each
# primitive's side is marked for the others' moves (the array a range is
# binned along moves with the rest).
# The bins' minima, maxima and counts merge exactly, so a range gets the same
# plane however many slices it was cut into.


@compiled.njit(nogil=True)
def _plan(level, bounds, p, piece, axis, lo, scale, mid, first_job):
    """For each wide range of the level, row, s, e, depth: the axis to
    bin (its centres' widest), its bin arithmetic, and mid: -1 for a SAH
    split, else the split point of a split by count (depth guard, or centres
    that coincide). The ranges cut in slices of at most `piece` primitives:
    jobs (J, 3) = range, s, e; first_job[k] is range k's first."""
    jobs = 0
    for k in range(level.shape[0]):
        jobs += (level[k, 2] - level[k, 1] + piece - 1) // piece
    out = np.empty((jobs, 3), np.int64)
    j = 0
    for k in range(level.shape[0]):
        s, e, d = level[k, 1], level[k, 2], level[k, 3]
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
            mid[k] = _median_split(p, s, e, cbox)
        first_job[k] = j
        for a0 in range(s, e, piece):
            out[j, 0] = k
            out[j, 1] = a0
            out[j, 2] = min(a0 + piece, e)
            j += 1
    first_job[level.shape[0]] = j
    return out


@compiled.njit(nogil=True)
def _bin_jobs(level, jobs, p, axis, lo, scale, mid, counts, bins, first, step):
    """Bin the slices jobs[first::step] of SAH ranges along their range's
    axis: counts[j]; bins[j]: each bin's box, then its centres' box."""
    last = BINS - 1
    # each thread bins in its own arrays: bins[j] beside another thread's
    # bins[j + 1] share cache lines, which all the threads write, every primitive
    # (what that cost: docs/notes/gpu-build.md#the-build-on-every-thread-kept)
    n = np.empty(BINS, np.int64)
    b = np.empty((BINS, 12), np.float32)
    for j in range(first, jobs.shape[0], step):
        k = jobs[j, 0]
        if mid[k] >= 0:
            continue
        x, y, z, ph, _ = p
        a = axis[k]
        key = x if a == 0 else (y if a == 1 else z)
        c, sa = lo[k], scale[k]
        _clear_bins(n, b)
        for i in range(jobs[j, 1], jobs[j, 2]):
            xi, yi, zi, hi = x[i], y[i], z[i], ph[i]
            kb = min(int((key[i] - c) * sa), last)
            n[kb] += 1
            b[kb, 0] = min(b[kb, 0], xi - hi)
            b[kb, 1] = min(b[kb, 1], yi - hi)
            b[kb, 2] = min(b[kb, 2], zi - hi)
            b[kb, 3] = max(b[kb, 3], xi + hi)
            b[kb, 4] = max(b[kb, 4], yi + hi)
            b[kb, 5] = max(b[kb, 5], zi + hi)
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
    each slice's primitives go: left_at[j], right_at[j]. Returns the split points."""
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
        for j in range(j0, j1):  # each slice's primitives that go left, for now in right_at
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
def _mark_jobs(jobs, done, p, dst, axis, lo, scale, mid, cut, left, left_at, right_at, first, step):
    """The first of a level's moves: the indices (p's last array) into dst, as _move_jobs moves
    the other arrays after it (the ranges done copied too), each primitive's side marked for
    those moves: left[i] is 1 where primitive i of the slices jobs[first::step] goes to its
    range's left child."""
    last = BINS - 1
    idx = p[4]
    for j in range(first, jobs.shape[0], step):
        k = jobs[j, 0]
        a = axis[k]
        key = p[0] if a == 0 else (p[1] if a == 1 else p[2])
        c, sa, kb, split = lo[k], scale[k], cut[k], mid[k]
        lt, rt = left_at[j], right_at[j]
        for i in range(jobs[j, 1], jobs[j, 2]):
            go = (i < split) if split >= 0 else (min(int((key[i] - c) * sa), last) <= kb)
            left[i] = go
            lt, rt = _put(dst, idx[i], np.int64(go), lt, rt)
    _copy_done(done, idx, dst, first, step)


@compiled.njit(nogil=True)
def _move_jobs(jobs, done, src, dst, left, left_at, right_at, first, step):
    """One of the builder's arrays, src, into dst: the slices jobs[first::step]
    each moved in order, its left side from left_at[j] on, its right side from
    right_at[j] on, each primitive to the side _mark_jobs marked; the ranges
    done[first::step] copied where they are."""
    for j in range(first, jobs.shape[0], step):
        lt, rt = left_at[j], right_at[j]
        for i in range(jobs[j, 1], jobs[j, 2]):
            lt, rt = _put(dst, src[i], np.int64(left[i]), lt, rt)
    _copy_done(done, src, dst, first, step)


@compiled.njit(nogil=True, inline="always")
def _put(dst, value, go, lt, rt):
    """value to dst's next place on its side (go: 1 for the left, where lt is, else 0 for the
    right, where rt is), without a branch: a slice's sides mix, and mispredicted the branch was
    most of a move. Returns the next places, lt and rt."""
    dst[rt + go * (lt - rt)] = value
    return lt + go, rt + 1 - go


@compiled.njit(nogil=True)
def _copy_done(done, src, dst, first, step):
    """The ranges done[first::step] (subtrees already set apart: s, e) copied from src to dst
    where they are."""
    for t in range(first, done.shape[0], step):
        dst[done[t, 0] : done[t, 1]] = src[done[t, 0] : done[t, 1]]


@compiled.njit(nogil=True)
def _attach(level, m, mid, children, p, nodes, links, used, wide):
    """Store each range's two children in its row: ranges of over `wide`
    primitives get a row and go to the next level (returned with their bounds);
    the others are subtree tasks (parent row, slot, s, e, depth).
    Returns (next level, its bounds, subtrees, rows used)."""
    n = level.shape[0]
    nxt = np.empty((2 * n, 4), np.int64)
    nxt_bounds = np.empty((2 * n, 12), np.float32)
    subtrees = np.empty((2 * n, 5), np.int64)
    nn = 0
    ns = 0
    for k in range(n):
        row, s, e, d = level[k, 0], level[k, 1], level[k, 2], level[k, 3]
        for slot in range(2):
            cs, ce = (s, m[k]) if slot == 0 else (m[k], e)
            b = children[k, slot]
            if mid[k] >= 0:  # split by count: no bins gave the bounds
                _range_bounds(p, cs, ce, b[:6], b[6:])
            nodes[row, CHILD_BOX[slot] : CHILD_BOX[slot] + BOX_FLOATS] = b[:6]
            links[row, REF + slot] = cs
            links[row, COUNT + slot] = ce - cs
            if ce - cs > wide:
                _open_row(nodes, links, row, slot, used)
                nxt[nn, 0], nxt[nn, 1], nxt[nn, 2], nxt[nn, 3] = used, cs, ce, d + 1
                nxt_bounds[nn] = b
                nn += 1
                used += 1
            else:
                subtrees[ns, 0], subtrees[ns, 1], subtrees[ns, 2] = row, slot, cs
                subtrees[ns, 3], subtrees[ns, 4] = ce, d
                ns += 1
    return nxt[:nn], nxt_bounds[:nn], subtrees[:ns], used


@compiled.njit(nogil=True)
def _grow_subtrees(p, nodes, links, tasks, base, ends, depths, first, step, node_cost):
    """Build the subtrees tasks[first::step], each into its block of rows
    from base + its first primitive (_grow's node_cost)."""
    stack = _stack()
    for t in range(first, tasks.shape[0], step):
        parent, slot, s, e, d = tasks[t, 0], tasks[t, 1], tasks[t, 2], tasks[t, 3], tasks[t, 4]
        _push(stack, 0, parent, slot, s, e, d)
        ends[t], depths[t] = _grow(p, nodes, links, stack, 1, base + s, node_cost)


@compiled.njit(nogil=True)
def _leaves_slices(items, order, piece, ordered, first, step):
    """The leaf buffer's columns in slices of `piece`, the j-th for j in first::step (_leaves)."""
    n = order.shape[0]
    for j in range(first, (n + piece - 1) // piece, step):
        _leaves(items, order, j * piece, min(j * piece + piece, n), ordered)


@compiled.njit(nogil=True)
def _prepare_slices(items, p, piece, bounds, first, step):
    """_prepare the j-th slice of piece primitives into bounds[j], for j in first::step."""
    n = p[0].shape[0]
    for j in range(first, bounds.shape[0], step):
        a = j * piece
        _prepare(items, p, a, min(a + piece, n), bounds[j])


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
# (docs/notes/gpu-build.md#the-build-on-every-thread-kept).
@compiled.njit(nogil=True, parallel=True)
def _prepare_all(items, p, piece, bounds, parts):
    for w in numba.prange(parts):
        _prepare_slices(items, p, piece, bounds, w, parts)


@compiled.njit(nogil=True, parallel=True)
def _bin_all(level, jobs, p, axis, lo, scale, mid, counts, bins, parts):
    for w in numba.prange(parts):
        _bin_jobs(level, jobs, p, axis, lo, scale, mid, counts, bins, w, parts)


@compiled.njit(nogil=True, parallel=True)
def _mark_all(jobs, done, p, dst, axis, lo, scale, mid, cut, left, left_at, right_at, parts):
    for w in numba.prange(parts):
        _mark_jobs(jobs, done, p, dst, axis, lo, scale, mid, cut, left, left_at, right_at, w, parts)


@compiled.njit(nogil=True, parallel=True)
def _move_all(jobs, done, src, dst, left, left_at, right_at, parts):
    for w in numba.prange(parts):
        _move_jobs(jobs, done, src, dst, left, left_at, right_at, w, parts)


@compiled.njit(nogil=True, parallel=True)
def _grow_all(p, nodes, links, tasks, base, ends, depths, parts, node_cost):
    for w in numba.prange(parts):
        _grow_subtrees(p, nodes, links, tasks, base, ends, depths, w, parts, node_cost)


@compiled.njit(nogil=True, parallel=True)
def _leaves_all(items, order, piece, ordered, parts):
    for w in numba.prange(parts):
        _leaves_slices(items, order, piece, ordered, w, parts)


@compiled.njit(nogil=True, parallel=True)
def _pack_all(nodes, links, tasks, base, ends, starts, packed, packed_links, parts):
    for w in numba.prange(parts):
        _pack(nodes, links, tasks, base, ends, starts, packed, packed_links, w, parts)


def _piece(primitives: int, threads: int) -> int:
    """Primitives per slice of a level of wide ranges: a few slices per thread."""
    return min(SLICE, max(1024, primitives // (4 * threads)))


def _build_wide(items, n: int, threads: int, wide: int, node_cost=NODE_COST):
    """The tree of the n > wide primitives of items (a scene's buffer, or a mesh's pair): its
    top level by level, each range of over `wide` primitives split by all
    threads, then the subtrees below on one thread each, each into its own
    block of rows, then the blocks packed after the top's rows. Returns
    (nodes, order, deepest depth); leaf_buffer makes the leaf buffer after,
    when the builder's arrays are gone."""
    p = tuple(scratch(n, t) for t in (np.float32,) * 4 + (np.int32,))  # sah_steps.work_arrays, mapped
    spare, left = scratch(n, np.float32), scratch(n, np.uint8)
    # the top's rows, then one block per subtree at the top's row count plus
    # its first primitive: a subtree of k primitives has fewer than k inner nodes
    nodes = reserve(2 * n, NODE_FLOATS)
    links = nodes.view(np.int32)
    piece = _piece(n, threads)
    parts = np.empty(((n + piece - 1) // piece, 12), np.float32)
    _prepare_all(items, p, piece, parts, threads)
    _empty_children(nodes, 0)
    level = np.array([[0, 0, n, 1]], np.int64)  # row, s, e, the row's depth
    bounds = parts[:1].copy()  # the slices' bounds merged: the root's
    _merge(bounds[0], parts)
    used, depth, subtrees = 1, 1, [np.empty((0, 5), np.int64)]
    while len(level):
        k = len(level)
        axis, lo, scale = np.empty(k, np.int64), np.empty(k, np.float32), np.empty(k, np.float32)
        mid, first_job, cut = np.empty(k, np.int64), np.empty(k + 1, np.int64), np.zeros(k, np.int64)
        jobs = _plan(
            level,
            bounds,
            p,
            _piece(int((level[:, 2] - level[:, 1]).sum()), threads),
            axis,
            lo,
            scale,
            mid,
            first_job,
        )
        counts, bins = np.empty((len(jobs), BINS), np.int64), np.empty((len(jobs), BINS, 12), np.float32)
        _bin_all(level, jobs, p, axis, lo, scale, mid, counts, bins, threads)
        left_at, right_at = np.empty(len(jobs), np.int64), np.empty(len(jobs), np.int64)
        children = np.empty((k, 2, 12), np.float32)
        m = _choose(level, jobs, first_job, axis, scale, mid, counts, bins, cut, left_at, right_at, children)
        done = np.ascontiguousarray(np.concatenate(subtrees)[:, 2:4])  # set apart: copied as they are
        plan, sides = (axis, lo, scale, mid, cut), (left, left_at, right_at)
        p, spare = _move(jobs, level[:, 1:3].copy(), done, p, spare, plan, sides, threads)
        depth = max(depth, int(level[:, 3].max()))
        level, bounds, below, used = _attach(level, m, mid, children, p, nodes, links, used, wide)
        subtrees.append(below)
    del spare, left
    tasks, runs, ranks = _in_runs(np.concatenate(subtrees), n, RUNS if mapped(p[0]) else 1)
    ends, depths = np.empty(len(tasks), np.int64), np.empty(len(tasks), np.int64)
    # subtrees differ in cost: more parts than threads, handed out one at a time as threads come free
    chunk = numba.set_parallel_chunksize(1)
    try:
        for a, b, s, e in runs:
            _grow_all(p, nodes, links, tasks[a:b], used, ends[a:b], depths[a:b], 4 * threads, np.float32(node_cost))
            for array in p[:4]:
                release(array, s, e)
    finally:
        numba.set_parallel_chunksize(chunk)
    order = p[4]
    # the work arrays but the order let go before the packed copy is made
    del p
    sizes = np.empty_like(ends)
    sizes[ranks] = ends - (used + tasks[:, 2])  # in the order the blocks are packed in
    starts = (used + np.cumsum(sizes) - sizes)[ranks]
    packed = np.empty((used + int(sizes.sum()), NODE_FLOATS), np.float32)
    packed[:used] = nodes[:used]
    for a, b, s, e in runs:
        _pack_all(nodes, links, tasks[a:b], used, ends[a:b], starts[a:b], packed, packed.view(np.int32), threads)
        release(nodes, used + s, used + e)
    return packed, order, max(depth, int(depths.max()))


def _move(jobs, ranges, done, p, spare, plan, sides, threads):
    """Move each of the builder's arrays p by the level's slices through the one spare array,
    the indices first (_mark_all, which marks each primitive's side for the rest). Returns the
    arrays and the spare array left over. Where more primitives are already set apart in
    subtrees (done) than the level's ranges hold, each array's moved ranges are copied back
    from the spare; else the ranges set apart are copied across, and the spare takes the
    array's place."""
    back = int((ranges[:, 1] - ranges[:, 0]).sum()) < int((done[:, 1] - done[:, 0]).sum())
    kept = done[:0] if back else done
    for a in (4, 0, 1, 2, 3):
        source = p[a]
        into = spare.view(source.dtype)
        if a == 4:
            _mark_all(jobs, kept, p, into, *plan, *sides, threads)
        else:
            _move_all(jobs, kept, source, into, *sides, threads)
        if back:
            _move_all(jobs[:0], ranges, into, source, *sides, threads)
        else:
            p, spare = p[:a] + (into,) + p[a + 1 :], source.view(np.float32)
    return p, spare


def _in_runs(tasks, n: int, runs: int):
    """The subtree tasks in runs along the primitives (RUNS), each run's largest first; the runs,
    each (its first task, the task after its last, its first primitive, the primitive after its
    last), which in order cover the primitives from the first to the last; and each task's rank
    in the order their blocks are packed in, along the primitives, so that a run's blocks are
    packed side by side."""
    tasks = tasks[np.argsort(tasks[:, 2])]
    run = tasks[:, 2] * runs // n
    ranks = np.lexsort((tasks[:, 2] - tasks[:, 3], run))
    edges = [int(e) for e in np.unique(np.searchsorted(run[ranks], np.arange(runs + 1)))]
    # tasks[edges] are the runs' first tasks in position order too: a run's first primitive
    starts = [int(tasks[e, 2]) for e in edges[:-1]] + [n]
    return tasks[ranks], list(zip(edges, edges[1:], starts, starts[1:])), ranks


def leaf_buffer(items, order, leaf_rows: int, threads: int, memory: str = "C") -> np.ndarray:
    """The tree's leaf buffer (leaf_rows, n): the primitives of the scene's
    buffer items in the tree's order, copied by every thread; held in
    memory "C" (a row a value) or "F" (a primitive's values together)."""
    ordered = np.empty((leaf_rows, order.shape[0]), np.float32, order=memory)
    _leaves_all(items, order, _piece(order.shape[0], threads), ordered, threads)
    return ordered
