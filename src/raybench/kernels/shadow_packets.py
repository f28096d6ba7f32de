"""The CPU's shadow rays as packets: a hit's shadow rays to one light, its
samples LANES at a time, walk the 4-wide tree together, any hit, each with
its own length; and the last blocker first (Haines and Greenberg's shadow
cache). The answer is traverse.walk's any hit, ray by ray.
"""

from collections import namedtuple

import numba
import numpy as np

from .. import compiled
from ..layout import PAD
from ..lighting import MAX_LIGHTS
from .constants import ZERO
from .packets import (
    _hit_ahead_from,
    _inverse,
    _leaf_missed,
    _meets_own,
    _read_leaf,
    _seen_from,
    packet_walk,
)

# A hit's shadow rays to one light, traced together: its samples,
# LANES at a time, walk the 4-wide tree as one packet of rays from one origin
# (the hit point), any hit, each ray with its own length (the distance to
# its sample) and done once blocked, the packet once all are
# (_shadow_packet). The pixel program, written once, calls them through
# whitted.make's `shadows` pair: cast traces a light's samples before its
# loop over them, blocked reads the answer. LANES: the loops over a packet's
# rays become SIMD only from 16 (LLVM's loop vectoriser leaves loops of fewer
# iterations scalar: tried 4 and 8, also with the rays' bits ORed as
# packet_boxes.wide_mask does), so a light of 4 samples fills a quarter of the lanes;
# they cost little next to four rays' scalar walks
# (docs/notes/whitted-cpu.md#cpu-shadow-rays-as-packets-issue-27).
LANES = 16
_DEAD = np.float32(-np.inf)  # a lane's length once blocked or where no ray is cast: no box is entered
# The last blockers' slots (_last_blocker), a pair of the sphere the rays
# leave and the light to one slot: prime, so that neighbouring spheres'
# pairs spread over all of them.
BLOCKER_SLOTS = 251


def _packet_shadows(jit, find, toward):
    """whitted.make's `shadows` for the CPU's packets: (cast, blocked).
    tree: the packets program's PacketsTree (below: the trees, then the
    thread's own scratch, _whitted_rows_packets)."""

    @jit
    def cast(px, py, pz, nx, ny, nz, light, samples, share, own, own_inside, spheres, count, lights, pattern, tree,
             stack_row, stack_t):  # fmt: skip
        """Bit s set where sample s's ray is blocked; 0 for samples whose
        ray is not cast (toward's facing 0)."""
        rays = tree.rays
        blockers = tree.blockers
        slot = (own * MAX_LIGHTS + light) % BLOCKER_SLOTS
        batch = np.int64(0)
        for first in range(0, samples, LANES):
            live = np.int64(0)
            lead = -1
            for k in range(LANES):
                s = first + k
                rays[_LEN, k] = _DEAD
                if s < samples:
                    lx, ly, lz, dist, facing, _r, _g, _b = toward(px, py, pz, nx, ny, nz, light, s, share, lights,
                                                                  pattern)  # fmt: skip
                    if facing > ZERO:
                        rays[_DX, k] = lx
                        rays[_DY, k] = ly
                        rays[_DZ, k] = lz
                        rays[_LEN, k] = dist
                        live |= np.int64(1) << np.int64(k)
                        if lead < 0:
                            lead = k
            if lead < 0:
                continue
            if _last_blocker(px, py, pz, rays, tree.ordered, tree.order, blockers[slot], own, own_inside) == _DEAD:
                batch |= live << np.int64(first)  # every ray blocked by the sphere that blocked the last
                continue
            for k in range(LANES):  # lanes without a ray follow the first live one: the spread stays tight
                if not (live >> np.int64(k)) & np.int64(1):
                    rays[_DX, k] = rays[_DX, lead]
                    rays[_DY, k] = rays[_DY, lead]
                    rays[_DZ, k] = rays[_DZ, lead]
            batch |= _shadow_packet(px, py, pz, rays, tree, own, own_inside, live, slot) << np.int64(first)
        return batch

    @jit
    def blocked(batch, s, px, py, pz, lx, ly, lz, dist, own, own_inside, spheres, count, tree, stack_row, stack_t):
        return (batch >> np.int64(s)) & np.int64(1) != 0

    return cast, blocked


# The packets program's tree and a thread's scratch, the `tree` that its
# pixel program passes down (backends/cpu/whitted_rows.py makes one a
# thread): the binary tree's four arrays first (trace.search_tree reads them
# by position), the wide tree's two, the shadow packets' rays, spread, stack
# and its entries' places along the first ray (_shadow_packet), the tile's
# primary hits, t and data (_tile_primaries), the lane of the pixel being shaded, the single-ray
# walk's stack (refs, counts, entry distances), and the last blockers (rows
# of `ordered`, -1 for none) by primitive and light (_last_blocker).
PacketsTree = namedtuple(
    "PacketsTree",
    "nodes links ordered order wide wide_links rays spread stack along hit closest hit_d lane s_ref "
    "s_count s_t blockers",
)


# A shadow packet's rows (_packet_shadows' rays): directions, their
# inverses, lengths. The loops index the one array by row, not through a row
# per name: each slice taken costs the runtime's reference counting, calls
# that were a large part of a packet's fixed cost.
_DX, _DY, _DZ, _IX, _IY, _IZ, _LEN = range(7)


@numba.njit(inline="always", error_model="numpy")
def _lanes_enter(lx, ly, lz, hx, hy, hz, rays):
    """_rows_enter for a shadow packet: 0 where any of its LANES rays enters
    the box (planes relative to their origin) nearer than its length, else -1
    (its one row)."""
    entered = False
    for k in range(LANES):
        t1, t2 = lx * rays[_IX, k], hx * rays[_IX, k]
        t3, t4 = ly * rays[_IY, k], hy * rays[_IY, k]
        t5, t6 = lz * rays[_IZ, k], hz * rays[_IZ, k]
        near = max(min(t1, t2), max(min(t3, t4), min(t5, t6)))
        far = min(max(t1, t2), min(max(t3, t4), max(t5, t6)))
        entered |= (near <= far) & (far > ZERO) & (near <= rays[_LEN, k])
    return np.int64(0) if entered else np.int64(-1)


@numba.njit(inline="always", error_model="numpy")
def _lanes_leaf(ox, oy, oz, margin, rays, spread, ordered, order, first, count, own, own_inside, blockers, slot):
    """A leaf's primitives against a shadow packet's rays: whether one of them
    blocks a ray (0 < t < the ray's length), each such ray's length made
    _DEAD. The test of traverse.leaf_test, on the same float32 values: the
    primitive `own` the rays leave skipped unless the primitive says a ray
    can meet it again (meets_own). A primitive whose padded box no ray enters is
    skipped after one test for the packet (packet_boxes.missed_by_all, as packets.packet_leaf
    does). The loop over the rays has no branch and no reduction but an OR:
    LLVM makes it SIMD. blockers[slot]: the last primitive found blocking a
    ray, tested first by the next packet of the slot (_last_blocker)."""
    hits = False
    for j in range(first, first + count):
        original = order[j]
        if original == own and not _meets_own(own_inside):
            continue
        row = _read_leaf(ordered, j)  # read once, for the box test and the rays' tests
        if _leaf_missed(row, ox, oy, oz, margin, spread):
            continue
        if _lanes_hit(_seen_from(row, ox, oy, oz), rays, original == own):
            blockers[slot] = j
            hits = True
    return hits


@compiled.leaf_test(error_model="numpy")
def _lanes_hit(seen, rays, is_own):
    """One primitive, as seen from the rays' origin (the primitive's
    seen_from), against a shadow packet's rays: each ray it blocks (0 < t <
    the ray's length) made _DEAD; whether it blocked one."""
    hits = False
    for k in range(LANES):
        t, _d = _hit_ahead_from(seen, rays[_DX, k], rays[_DY, k], rays[_DZ, k], is_own)
        c = rays[_LEN, k]
        hit = (t > ZERO) & (t < c)
        rays[_LEN, k] = _DEAD if hit else c
        hits |= hit
    return hits


# A light's shadow rays from neighbouring points, the tile's pixels one
# after another, are mostly blocked by one sphere: tested first, it answers
# them without a walk. The answer is the walk's (any hit: which sphere
# blocks does not matter), on the same float32 values as _lanes_leaf's. A
# call, not inlined: as fast a frame, for less of the first frame's compile
# (docs/notes/whitted-cpu.md#cpu-the-last-blocker-first-issue-27).
@compiled.njit(nogil=True, error_model="numpy", _nrt=False)
def _last_blocker(ox, oy, oz, rays, ordered, order, j, own, own_inside):
    """A shadow packet's rays from (ox, oy, oz) against row j of `ordered`
    (none where j < 0 or it is the sphere the rays leave from outside), each
    ray it blocks made _DEAD: the packet's reach after it (_DEAD once every
    ray is blocked)."""
    if j >= 0:
        original = order[j]
        if original != own or _meets_own(own_inside):
            _lanes_hit(_seen_from(_read_leaf(ordered, j), ox, oy, oz), rays, original == own)
    return _reach(rays)


@numba.njit(inline="always")
def _reach(rays):
    """The packet's longest ray: _DEAD once every ray is blocked."""
    reach = rays[_LEN, 0]
    for k in range(1, LANES):
        reach = max(reach, rays[_LEN, k])
    return reach


@numba.njit(inline="always", error_model="numpy")
def _shadow_enter(lx, ly, lz, hx, hy, hz, rays, start):
    """packet_walk's box test for a shadow packet (_lanes_enter; one row, so
    no start)."""
    return _lanes_enter(lx, ly, lz, hx, hy, hz, rays[0])


@numba.njit(inline="always", error_model="numpy")
def _shadow_leaf(ox, oy, oz, margin, spread, ref, count, rays):
    """packet_walk's leaf for a shadow packet: _lanes_leaf, then the packet's
    reach shortened to its longest ray left; True once every ray is blocked,
    which ends the walk."""
    lanes, ordered, order, own, own_inside, blockers, slot = rays
    if count > 0 and _lanes_leaf(ox, oy, oz, margin, lanes, spread, ordered, order, ref, count, own, own_inside,
                                 blockers, slot):  # fmt: skip
        reach = _reach(lanes)
        if reach == _DEAD:
            return True
        spread[6] = reach
    return False


_walk_any = packet_walk(_shadow_enter, _shadow_leaf, any_hit=True)


# Inlined into the pixel program (a call of its own measured slower,
# docs/notes/whitted-cpu.md#cpu-shadow-rays-as-packets-issue-27): compiled there with the
# program's error model, which leaves its loops over the rays SIMD (they
# divide by nothing).
@numba.njit(inline="always", error_model="numpy")
def _shadow_packet(ox, oy, oz, rays, tree, own, own_inside, live, slot):
    """Any hit of each of a shadow packet's rays from (ox, oy, oz) through
    the 4-wide tree (packet_walk's, its children ordered along the first
    ray): the bits of the rays blocked, of those in `live`.
    rays[_DX:_DZ + 1]: the unit directions; rays[_LEN]: each ray's length,
    _DEAD where no ray is cast or it is blocked already (_last_blocker)
    (rays[_IX:_IZ + 1]: their inverses, written here); tree: the
    PacketsTree, whose spread, stack and order scratch the walk uses. A ray
    is blocked where some primitive has 0 < t < its length, which no order
    of the walk changes: the answer of traverse.walk's any hit, ray by ray.
    tree.blockers[slot]: set to the last primitive that blocked a ray
    (_lanes_leaf)."""
    spread = tree.spread
    for k in range(LANES):
        rays[_IX, k] = _inverse(rays[_DX, k])
        rays[_IY, k] = _inverse(rays[_DY, k])
        rays[_IZ, k] = _inverse(rays[_DZ, k])
    for a in range(3):
        lo = hi = rays[_IX + a, 0]
        for k in range(1, LANES):
            lo = min(lo, rays[_IX + a, k])
            hi = max(hi, rays[_IX + a, k])
        spread[2 * a] = lo
        spread[2 * a + 1] = hi
    spread[6] = _reach(rays)
    margin = (abs(ox) + abs(oy) + abs(oz)) * PAD
    state = (rays, tree.ordered, tree.order, own, own_inside, tree.blockers, slot)
    # the stack again as the walk's counts: any hit pushes inner children alone, and keeps no counts
    _walk_any(tree.wide, tree.wide_links, ox, oy, oz, margin, rays[_DX, 0], rays[_DY, 0], rays[_DZ, 0], spread,
              tree.stack, tree.stack, tree.along, state)  # fmt: skip
    bits = np.int64(0)  # the rays blocked: those whose length was made _DEAD (a live ray's is positive)
    for k in range(LANES):
        if rays[_LEN, k] == _DEAD:
            bits |= np.int64(1) << np.int64(k)
    return bits & live
