"""The CPU's packets of primary rays: a 16x8 tile of pixels walks the tree
together, each node's boxes tested against all its rays at once (loops that
LLVM turns into SIMD), each ray still getting the nearest primitive of all it
could hit, ties to the smaller index: the pixels of kernels.traverse's walk,
one ray at a time. The walk is the 4-wide tree's (bvh.collapse:
_packet_walk_wide, and _bvh_packets_wide's rows); a leaf's primitives are
tested through the primitive's functions (kernels/primitives), seen from the
packet's shared origin.

fastmath stays off (backends/cpu): the float32 arithmetic is exactly IEEE.
"""

import functools

import numba
import numpy as np

from .. import compiled
from ..layout import (
    INNER,
    PAD,
    W_COUNT,
    W_REF,
    WIDE_FLOATS,
    WIDE_STACK,
    WIDTH,
)
from .constants import FAR, ZERO
from .footprint import OFF, frame_view, tree_window
from .packet_boxes import _U, missed_by_all, wide_mask, wide_planes
from .prefetch import prefetch
from .primitives import sphere
from .trace import make
from .tree_leaves import leaf_row, leaf_to_lanes


# The packets' own compile of the algorithm (kernels.make), with NumPy's error model, where
# backends/cpu/program.py's has Python's: float division then has no check for a zero divisor (none
# can occur: the divisors are the image size, a ray's length, a radius, a direction component raised
# to at least TINY), so the result is the same IEEE quotient, and LLVM can make the loops over a
# packet's rays SIMD, which the check's branch prevents (vdivps, vsqrtps in the assembly).
# Made for a primitive, the sphere's at import; compiled.rebound compiles
# this module again for another kind (backends/cpu/kinds.py).
@functools.cache
def _made(primitive=sphere):
    """kernels.make for the packets, with NumPy's error model, for one kind of primitive."""
    return make(numba.njit(inline="always", error_model="numpy"), primitive=primitive)


_kb = _made()
_primary_ray_v, _inverse = _kb.primary_ray, _kb.inverse
_shade_hit_v, _shade_miss_v, _to_byte_v = _kb.shade_hit, _kb.shade_miss, _kb.to_byte
# The primitive's functions (kernels/primitives): a leaf's row, its box and
# how the packet's shared origin sees it (the row read once for both), its
# tests from there, and what the thesis's shading divides by.
_prim = _kb.prim
_read_leaf, _box_of, _seen_from = _prim.read_leaf, _prim.box_of, _prim.seen_from
_hit_from, _hit_ahead_from = _prim.hit_from, _prim.hit_ahead_from
_leaf_hit_ahead, _meets_own, _rim, _colour = _prim.leaf_hit_ahead, _prim.meets_own, _prim.rim, _prim.colour
# A ray's own part of its test, worked out once a packet (aim), and a leaf's
# primitive turned once for rays that share it (turned, hit_aimed): the
# triangle's shear; another kind's are its hit_from (answers.unaimed).
_aim, _turned, _hit_aimed = _prim.aim, _prim.turned, _prim.hit_aimed
# The rays of a packet that a leaf's primitive can meet, by its footprint on
# the frame (kernels/footprint.py): the triangle's vertices', another kind's box's.
_window = _prim.window
# Which primitives are tested so (a kind of both's triangles), and the others' test on all the rays.
_footprinted, _hit_whole = _prim.footprinted, _prim.hit_whole


def _kind_constants(primitive) -> dict:
    """The packet's shape for a kind of primitive (its PACKET_SHAPE: width,
    height) and what follows from it; compiled.rebound puts them into the
    kind's copy of this module (and of whitted_rows, which tiles its frame by
    them). A kind's packet height divides the sphere's, PACKET_H below: the
    frame's bands and a cluster's tiles start on a multiple of it
    (backends/cpu/tracer.py), so every kind's packets fall on the rows the
    whole frame's would."""
    width, height = primitive.PACKET_SHAPE
    if sphere.PACKET_SHAPE[1] % height:
        raise ValueError(f"a packet's height must divide {sphere.PACKET_SHAPE[1]}, got {height}")
    return {"PACKET_W": width, "PACKET_H": height, "PACKET": width * height,
            "_MIDDLE": (height // 2) * width + width // 2, "FOOTPRINT": primitive.PACKET_FOOTPRINT,
            "LEAF_TOGETHER": primitive.CPU_LEAF_ORDER == "F", "LEAF_ROWS": primitive.LEAF_ROWS}  # fmt: skip


# Rays walked through the BVH together: a tile of pixels, for the sphere
# 16x8, eight AVX-512 or sixteen AVX2 registers of float32 per ray
# component; of 4x4 to 32x8, 16x8 was the fastest once the children were
# ordered along the middle ray (docs/notes/bvh-walk.md#measured-cpu-only-machine-amd-epyc-2-vcpus-shared).
# Each kind says its own (PACKET_SHAPE): a mesh's are the sphere's too.
_SHAPE = _kind_constants(sphere)
PACKET_W, PACKET_H, PACKET, _MIDDLE = _SHAPE["PACKET_W"], _SHAPE["PACKET_H"], _SHAPE["PACKET"], _SHAPE["_MIDDLE"]
# Whether a leaf's primitive is tested on the rays its footprint covers (footprint.py): the kind's PACKET_FOOTPRINT.
FOOTPRINT = _SHAPE["FOOTPRINT"]
# Whether a leaf's values lie together (CPU_LEAF_ORDER "F"): the walk fetches its first lines ahead (prefetch.py).
LEAF_TOGETHER = _SHAPE["LEAF_TOGETHER"]
# The rows of a leaf's primitive (the kind's LEAF_ROWS): packet_leaf copies a leaf's, LEAF_LANES at once.
LEAF_ROWS = _SHAPE["LEAF_ROWS"]
# The rays a packet's loops take at once where SIMD: 8 float64 lanes of AVX-512, two of AVX2 (_aimed_tests).
LANES = 8
# A leaf's primitives whose windows are worked out at once (packet_leaf), in `lanes`: LEAF_ROWS rows
# of 2 * LEAF_LANES float32, their rows in the first LEAF_LANES columns, their windows in the first
# four rows of the others (a kind's LEAF_ROWS is at least 4). 8 float64 lanes of AVX-512, two of AVX2.
LEAF_LANES = 8
# A packet's scratch (SCRATCH rows of PACKET + 1 float32): its rays' aim (_aim_packet).
# Float32 holds each exactly; one array keeps Numba's reference counting out of the walk.
SCRATCH = 4
# scratch[3, PACKET] until a leaf first needs the rays' aim (_aim_packet): a packet that meets none pays nothing.
UNAIMED = np.float32(-2.0)


@numba.njit(inline="always")
def _spread(ix, iy, iz, spread):
    """spread[:6]: the packet's range of inverse directions (x low, x high, ...); spread[6]: FAR, its farthest hit."""
    for a, inv in enumerate((ix, iy, iz)):
        lo = hi = inv[0]
        for k in range(1, PACKET):
            lo = min(lo, inv[k])
            hi = max(hi, inv[k])
        spread[2 * a] = lo
        spread[2 * a + 1] = hi
    spread[6] = FAR


@numba.njit(inline="always", error_model="numpy")
def _leaf_missed(row, ox, oy, oz, margin, spread):
    """Whether no ray of the packet from (ox, oy, oz) enters a leaf
    primitive's own box (row: its read_leaf), as the builder pads it, grown
    by margin as the walk grows boxes: one test for the packet
    (packet_boxes.missed_by_all)."""
    lx, ly, lz, hx, hy, hz = _box_of(row)
    return missed_by_all(
        lx - margin - ox,
        ly - margin - oy,
        lz - margin - oz,
        hx + margin - ox,
        hy + margin - oy,
        hz + margin - oz,
        spread,
    )


@numba.njit(inline="always", error_model="numpy")
def _rows_enter(lx, ly, lz, hx, hy, hz, ix, iy, iz, closest, start):
    """The row of the packet in which a ray enters the box of planes (lx,
    ..., hz) relative to the rays' origin nearer than its closest hit, or -1
    where none does: the rays a row of the packet at a time (SIMD), from row
    start on (round to the rows before it), stopping at the first row with a
    ray that enters (_packet_walk_wide)."""
    for i in range(_U(PACKET_H)):
        r = _U(start) + i
        r = r - _U(PACKET_H) if r >= _U(PACKET_H) else r
        first = r * _U(PACKET_W)
        entered = False
        for k in range(first, first + _U(PACKET_W)):
            t1, t2 = lx * ix[k], hx * ix[k]
            t3, t4 = ly * iy[k], hy * iy[k]
            t5, t6 = lz * iz[k], hz * iz[k]
            near = max(min(t1, t2), max(min(t3, t4), min(t5, t6)))
            far = min(max(t1, t2), min(max(t3, t4), max(t5, t6)))
            entered |= (near <= far) & (far > ZERO) & (near <= closest[k])
        if entered:
            return np.int64(r)
    return np.int64(-1)


@numba.njit(inline="always", error_model="numpy")
def _ray_tests(seen, original, dx, dy, dz, closest, hit, hit_d, ahead, first, end):
    """One primitive (seen_from the packet's origin) against the packet's
    rays first..end (packet_leaf), the walk's tie rule. first and end
    unsigned where they are not constants (_U): from a signed start the
    indices carry Python's negative-index wraparound, and LLVM left the loop
    scalar. Inlined in the thesis's packets for every kind: a mesh's frames
    are faster than through a call, for a longer first compile
    (docs/triangles.md#the-cpus-packets-a-triangle-meets-the-rows-it-covers)."""
    for k in range(first, end):
        if ahead:
            t, d = _hit_ahead_from(seen, dx[k], dy[k], dz[k], False)
        else:
            t, d = _hit_from(seen, dx[k], dy[k], dz[k])
        _better(t, d, k, original, closest, hit, hit_d)


@numba.njit(inline="always", error_model="numpy")
def _better(t, d, k, original, closest, hit, hit_d):
    """Ray k's closest hit, with t and d (its test of primitive `original`)
    if nearer, ties to the smaller index: the walk's tie rule."""
    c = closest[k]
    better = (t > ZERO) & ((t < c) | ((t == c) & (original < hit[k])))
    closest[k] = t if better else c
    hit[k] = original if better else hit[k]
    hit_d[k] = d if better else hit_d[k]


@numba.njit(inline="always", error_model="numpy")
def _aimed_tests(seen, original, dx, dy, dz, closest, hit, hit_d, first_row, end_row, first, end, scratch):
    """_ray_tests for the thesis's packets of a kind with FOOTPRINT: one
    primitive (seen_from the packet's origin) against the rays of rows
    first_row..end_row, columns first..end (unsigned, _U), through the
    rays' aim (_aim_packet's, in scratch): where the packet's rays share their
    kz, the primitive is turned for them once (_turned), not a ray at a
    time. The very values hit_from computes (hit_aimed's), so the same
    hits."""
    kz = np.int64(scratch[3, PACKET])
    if kz >= 0:
        turned = _turned(seen, kz)
        for r in range(first_row, end_row):
            for k in range(r * _U(PACKET_W) + first, r * _U(PACKET_W) + end):
                t, d = _hit_aimed(turned, scratch[0, k], scratch[1, k], scratch[2, k], dx[k], dy[k], dz[k])
                _better(t, d, k, original, closest, hit, hit_d)
    else:
        for r in range(first_row, end_row):
            for k in range(r * _U(PACKET_W) + first, r * _U(PACKET_W) + end):
                turned = _turned(seen, np.int64(scratch[3, k]))
                t, d = _hit_aimed(turned, scratch[0, k], scratch[1, k], scratch[2, k], dx[k], dy[k], dz[k])
                _better(t, d, k, original, closest, hit, hit_d)


@numba.njit(inline="always", error_model="numpy")
def _whole_tests(seen, original, dx, dy, dz, closest, hit, hit_d):
    """_ray_tests for a primitive that a kind with FOOTPRINT does not footprint
    (a sphere of a kind of both): every ray of the packet, by hit_whole."""
    for k in range(PACKET):
        t, d = _hit_whole(seen, dx[k], dy[k], dz[k])
        _better(t, d, k, original, closest, hit, hit_d)


@numba.njit(inline="always")
def _aim_packet(dx, dy, dz, scratch):
    """scratch[:3, k], scratch[3, k]: ray k's shear and kz (_aim);
    scratch[3, PACKET]: the kz that every ray of the packet shares, -1 if
    they do not (_aimed_tests). kz is stored as a float32 (0, 1 or 2,
    exact), so that one array holds it all (a first version with an array
    each spent most of the frame in Numba's reference counting, NRT_incref
    and NRT_decref, by perf)."""
    for k in range(PACKET):
        kz, scratch[0, k], scratch[1, k], scratch[2, k] = _aim(dx[k], dy[k], dz[k])
        scratch[3, k] = np.float32(kz)
    shared = scratch[3, 0]
    for k in range(1, PACKET):
        shared = shared if scratch[3, k] == shared else np.float32(-1.0)
    scratch[3, PACKET] = shared


@compiled.leaf_test(error_model="numpy")
def _packet_rays(seen, original, dx, dy, dz, closest, hit, hit_d, ahead, first, end):
    """_ray_tests for Whitted's primary packets (ahead): a call for a kind
    whose INLINE_TESTS is False, as in the other walks, whose programs
    compile long already."""
    _ray_tests(seen, original, dx, dy, dz, closest, hit, hit_d, ahead, first, end)


def packet_leaf(tests):
    """packet_walk's leaf for the closest hit (it never ends the walk): the
    exact test of a leaf's primitives on the packet's rays, seen from the
    packet's origin as the primitive's own test sees it (seen_from, on its
    row read once), by tests(seen, original, dx, dy, dz, closest, hit,
    hit_d, ahead, first, end) on the rays first..end, the walk's tie rule;
    the rays, _packet_walk_wide's. ahead: Whitted's primary rays' test
    (hit_ahead for a ray that leaves no primitive, as traverse.leaf_test
    makes it: for a sphere, the far root where the near one is behind, a
    camera inside it). A primitive whose own box (as the builder pads it,
    grown by margin as the walk grows boxes) no ray enters is skipped after
    one test for the packet (packet_boxes.missed_by_all); with FOOTPRINT, a
    primitive is tested on the rows and columns of rays its footprint covers,
    instead (its kind's window, footprint.py's; view, place: the frame's and
    the packet's; lanes: the windows' array), the thesis's rays through their aim
    (_aimed_tests; scratch: the packet's). One source for the thesis's
    packets, whose tests are inlined, and Whitted's (_packet_rays)."""

    @numba.njit(inline="always", error_model="numpy")
    def leaf(ox, oy, oz, margin, spread, first, count, rays):
        ordered, order, dx, dy, dz, _ix, _iy, _iz, closest, hit, hit_d, closest_bits, spread_bits = rays[:13]
        ahead, view, place, scratch, lanes = rays[13], rays[14], rays[15], rays[16], rays[17]
        if FOOTPRINT:
            # the windows first, then the tests of those with one (docs/triangles.md#a-leafs-windows-first-2026-12-05)
            for part in range(first, first + count, LEAF_LANES):
                end = min(part + LEAF_LANES, first + count)
                # the thesis's LEAF_LANES windows in one loop without a branch, which LLVM makes SIMD:
                # the rows copied side by side (in the buffer a lane's loads would be scattered), the
                # windows written beside them in the same array, where LLVM sees that they meet no read
                # (in another it would check at run time, which it does not for so few); lanes past the
                # leaf's end hold an earlier leaf's, never read. Whitted's frames were slower so: there
                # a window at a time (docs/notes/embree.md#a-leafs-windows-eight-at-a-time-2026-12-06)
                if not ahead:
                    for i in range(end - part):
                        leaf_to_lanes(ordered, part + i, lanes, i)
                for i in range(end - part if ahead else LEAF_LANES):
                    row = leaf_row(ordered, part + i) if ahead else _read_leaf(lanes, i)
                    window = _window(view, place, PACKET_H, PACKET_W, row, margin, ox, oy, oz)
                    for w in range(4):
                        lanes[w, LEAF_LANES + i] = np.float32(window[w])
                for j in range(part, end):
                    row = leaf_row(ordered, j) if ahead else _read_leaf(lanes, j - part)
                    if not _footprinted(row):  # tested at once (docs/notes/mixed-scenes.md)
                        if not _leaf_missed(row, ox, oy, oz, margin, spread):
                            if ahead:
                                tests(_seen_from(row, ox, oy, oz), order[j], dx, dy, dz, closest, hit, hit_d, ahead,
                                      0, PACKET)  # fmt: skip
                            else:
                                _whole_tests(_seen_from(row, ox, oy, oz), order[j], dx, dy, dz, closest, hit, hit_d)
                        continue
                    # the footprint stands in for the packet's interval test of the
                    # box, which almost every triangle of a dense mesh passes
                    i = LEAF_LANES + j - part
                    first_row, end_row = _U(lanes[0, i]), _U(lanes[1, i])
                    if first_row == end_row:
                        continue
                    # the columns widened to whole groups of LANES, which the
                    # loops' SIMD code takes at once (a loop of fewer goes a ray
                    # at a time)
                    first_lane = _U(lanes[2, i]) // _U(LANES) * _U(LANES)
                    end_lane = min((_U(lanes[3, i]) + _U(LANES - 1)) // _U(LANES) * _U(LANES),
                                   _U(PACKET_W))  # fmt: skip
                    seen = _seen_from(row, ox, oy, oz)
                    if ahead:
                        for r in range(first_row, end_row):
                            tests(seen, order[j], dx, dy, dz, closest, hit, hit_d, ahead, r * _U(PACKET_W) + first_lane,
                                  r * _U(PACKET_W) + end_lane)  # fmt: skip
                    else:
                        if scratch[3, PACKET] == UNAIMED:  # the packet's first test of its rays' aim
                            _aim_packet(dx, dy, dz, scratch)
                        _aimed_tests(seen, order[j], dx, dy, dz, closest, hit, hit_d, first_row, end_row, first_lane,
                                     end_lane, scratch)  # fmt: skip
        else:
            for j in range(first, first + count):
                row = leaf_row(ordered, j)  # read once, for the box test and the rays' tests
                if _leaf_missed(row, ox, oy, oz, margin, spread):
                    continue
                tests(_seen_from(row, ox, oy, oz), order[j], dx, dy, dz, closest, hit, hit_d, ahead, 0, PACKET)
        # spread[6] = the farthest closest hit: closest holds positive float32
        # only, whose bit patterns order as the floats do, so an integer maximum,
        # which LLVM makes SIMD (a float one it would not)
        m = closest_bits[0]
        for k in range(1, PACKET):
            m = max(m, closest_bits[k])
        spread_bits[6] = m
        return False

    return leaf


@numba.njit(inline="always", error_model="numpy")
def _colour_packet(x0, y0, spheres, hit, hit_d, rgb, paint):
    """rgb[c, k]: the bytes store_pixel writes for ray k of the packet, for
    every ray at once: first the hit primitives' colours and rims gathered
    (the primitive's colour and rim; a miss reads primitive 0's and drops
    them), then shaded in a loop without branches (each ray's hit and miss
    colours both computed, one kept), which LLVM makes SIMD. spheres must
    hold a primitive (Tracer.shaded)."""
    for k in range(PACKET):
        j = max(hit[k], 0)
        paint[0, k], paint[1, k], paint[2, k] = _colour(spheres, j)
        paint[3, k] = _rim(spheres, j)
    for k in range(PACKET):
        hr, hg, hb = _shade_hit_v(paint[0, k], paint[1, k], paint[2, k], paint[3, k], hit_d[k])
        mr, mg, mb = _shade_miss_v(np.float32(np.int32(x0 + k % PACKET_W)), np.float32(np.int32(y0 + k // PACKET_W)))
        got = hit[k] >= 0
        rgb[0, k] = _to_byte_v(hr if got else mr)
        rgb[1, k] = _to_byte_v(hg if got else mg)
        rgb[2, k] = _to_byte_v(hb if got else mb)


@numba.njit(inline="always")
def _put_pixel(y, x, k, rgb, hit, image, hits):
    """Store ray k's bytes and hit index at pixel (x, y), each at least 0,
    by unsigned indices (_U): a signed one costs Python's negative-index wraparound
    each store (docs/notes/embree.md#against-mitsuba-3-on-embree-side-by-side-2-vcpu-machine)."""
    y, x, k = _U(y), _U(x), _U(k)
    image[y, x, _U(0)] = rgb[_U(0), k]
    image[y, x, _U(1)] = rgb[_U(1), k]
    image[y, x, _U(2)] = rgb[_U(2), k]
    hits[y, x] = hit[k]


@numba.njit(inline="always")
def _start_packet(x0, y0, end_row, width, height, basis, dx, dy, dz, ix, iy, iz, closest, hit, hit_d, spread):
    """The packet of rays from pixel (x0, y0): their directions and inverses,
    nothing hit yet, and their spread (_spread). Inlined into each packet
    walk; separate loops, each simple enough for LLVM to make SIMD."""
    for k in range(PACKET):
        # rays off the chunk trace a copy of its last row or column, unstored; a pixel's
        # coordinates as int32 (exact: a side is at most limits.MAX_SIDE), which AVX2 turns into
        # float32 eight at a time (docs/notes/embree.md#against-mitsuba-3-on-embree-side-by-side-2-vcpu-machine)
        x = np.int32(min(x0 + k % PACKET_W, width - 1))
        y = np.int32(min(y0 + k // PACKET_W, end_row - 1))
        dx[k], dy[k], dz[k] = _primary_ray_v(x, y, width, height, basis)
    for k in range(PACKET):
        ix[k] = _inverse(dx[k])
        iy[k] = _inverse(dy[k])
        iz[k] = _inverse(dz[k])
    for k in range(PACKET):
        closest[k] = FAR
        hit[k] = -1
        hit_d[k] = ZERO
    _spread(ix, iy, iz, spread)


@numba.njit(inline="always")
def _store_packet(x0, y0, end_row, width, spheres, hit, hit_d, rgb, paint, image, hits):
    """The packet's pixels shaded and stored, those inside the frame's rows."""
    _colour_packet(x0, y0, spheres, hit, hit_d, rgb, paint)
    if x0 + PACKET_W <= width and y0 + PACKET_H <= end_row:
        # a whole packet: rows of pixels stored without a test each
        for line in range(PACKET_H):
            for i in range(PACKET_W):
                _put_pixel(y0 + line, x0 + i, line * PACKET_W + i, rgb, hit, image, hits)
    else:
        for k in range(PACKET):
            x = x0 + k % PACKET_W
            y = y0 + k // PACKET_W
            if x < width and y < end_row:
                _put_pixel(y, x, k, rgb, hit, image, hits)


def packet_walk(enter, leaf, any_hit):
    """The CPU's walk of a packet of rays from one origin through the 4-wide
    tree, for the closest hit (the thesis's and Whitted's primary rays,
    _packet_walk_wide) or any hit (shadow rays, shadow_packets): one source.
    walk(wide, wide_links, ox, oy, oz, margin, cdx, cdy, cdz, spread,
    stack_row, stack_count, along, rays): a node's four boxes go through the
    packet's interval test together (packet_boxes.wide_mask), then each box
    it leaves through the rays' own test (enter(lx, ly, lz, hx, hy, hz,
    rays, start): the row in which a ray enters it, or -1, from row start,
    the last box's); the children entered are pushed nearest on top along
    (cdx, cdy, cdz) and popped until an inner child is, walked next: a leaf
    popped is tested then (leaf(ox, oy, oz, margin, spread, ref, count,
    rays)), so the farther leaves wait for a near inner child's hits. Any hit
    tests a leaf as soon as the rays enter it, so that the rays it blocks
    enter none of the node's later children, pushes inner children alone,
    and ends once leaf returns True (every ray blocked). The closest hit asks
    the caches for an entered child's first lines as it pushes it
    (kernels/prefetch.py). along: scratch for the children's places.
    Inlined where it is called, with the caller's error model (_kb's note)."""

    @numba.njit(inline="always", error_model="numpy")
    def walk(wide, wide_links, ox, oy, oz, margin, cdx, cdy, cdz, spread, stack_row, stack_count, along, rays):
        row = 0
        top = 0
        # the row of the packet where the last box entered was entered: the
        # next box's test starts there (its neighbour in the walk, most often
        # entered by the same rows)
        hint = 0
        while row >= 0:
            mask = wide_mask(wide, row, ox, oy, oz, margin, spread)
            base = top
            for c in range(WIDTH):
                if not (mask >> c) & 1:
                    continue
                lx, ly, lz, hx, hy, hz = wide_planes(wide, row, c, ox, oy, oz, margin)
                entered = enter(lx, ly, lz, hx, hy, hz, rays, hint)
                if entered < 0:
                    continue
                hint = entered
                ref, count = wide_links[row, W_REF + c], wide_links[row, W_COUNT + c]
                if not any_hit:  # what the child will read, asked for now (kernels/prefetch.py)
                    if count == INNER:
                        prefetch(wide, ref, 0)
                        prefetch(wide, ref, WIDE_FLOATS // 2)
                    elif LEAF_TOGETHER:
                        prefetch(rays[0], 0, ref)
                        prefetch(rays[0], 0, ref + 3)  # a primitive is over half a line: the fourth a line or two on
                if any_hit and count != INNER:
                    if leaf(ox, oy, oz, margin, spread, ref, count, rays):
                        return
                    continue
                # insertion among this node's children, the nearest on top
                place = (lx + hx) * cdx + (ly + hy) * cdy + (lz + hz) * cdz
                j = top
                while j > base and along[j - base - 1] < place:
                    stack_row[j] = stack_row[j - 1]
                    if not any_hit:  # any hit pushes inner children alone
                        stack_count[j] = stack_count[j - 1]
                    along[j - base] = along[j - base - 1]
                    j -= 1
                stack_row[j] = ref
                if not any_hit:
                    stack_count[j] = count
                along[j - base] = place
                top += 1
            row = -1
            # any hit's stack holds inner children alone: the next one popped
            # in one step (the closest hit's pop loop, shared, cost Whitted's
            # frames: docs/notes/one-source.md#the-cpus-packet-walks-one-source)
            if any_hit:
                if top > 0:
                    top -= 1
                    row = stack_row[top]
            else:
                while row < 0 and top > 0:
                    top -= 1
                    if stack_count[top] == INNER:
                        row = stack_row[top]
                    else:
                        leaf(ox, oy, oz, margin, spread, stack_row[top], stack_count[top], rays)

    return walk


@numba.njit(inline="always", error_model="numpy")
def _closest_enter(lx, ly, lz, hx, hy, hz, rays, start):
    """packet_walk's box test for the closest hit (_rows_enter)."""
    return _rows_enter(lx, ly, lz, hx, hy, hz, rays[5], rays[6], rays[7], rays[8], start)


def packet_walk_wide(walk, ahead):
    """The closest hit of every ray of a packet (started by _start_packet)
    through walk (packet_walk's): closest, hit and hit_d; ahead: the leaf's
    test for Whitted's primary rays (packet_leaf); view, place: the frame's
    (_frame_view) and the packet's (_place), its scratch (the rays' aim) and
    lanes (a leaf's primitives side by side, and their windows), for the leaf."""

    @numba.njit(inline="always", error_model="numpy")
    def walk_packet(wide, wide_links, ordered, order, ox, oy, oz, margin, dx, dy, dz, ix, iy, iz, closest, hit,
                    hit_d, spread, closest_bits, spread_bits, stack_row, stack_count, along, view, place,
                    scratch, lanes):  # fmt: skip
        rays = (ordered, order, dx, dy, dz, ix, iy, iz, closest, hit, hit_d, closest_bits, spread_bits, ahead, view,
                place, scratch, lanes)  # fmt: skip
        walk(wide, wide_links, ox, oy, oz, margin, dx[_MIDDLE], dy[_MIDDLE], dz[_MIDDLE], spread, stack_row,
             stack_count, along, rays)  # fmt: skip

    return walk_packet


# Each a name of the module, so that compiled.rebound copies each for a kind
# (it swaps what a closure holds as it swaps globals): the thesis's packets
# (_bvh_packets_wide) and Whitted's primary ones (whitted_rows), which call
# their leaf's test (_packet_rays) where the thesis's inline it.
_leaf_thesis = packet_leaf(_ray_tests)
_leaf_ahead = packet_leaf(_packet_rays)
_walk_thesis = packet_walk(_closest_enter, _leaf_thesis, any_hit=False)
_walk_ahead = packet_walk(_closest_enter, _leaf_ahead, any_hit=False)
_packet_walk_wide = packet_walk_wide(_walk_thesis, False)
_packet_walk_ahead = packet_walk_wide(_walk_ahead, True)


@numba.njit(inline="always")
def _frame_view(basis, width, height):
    """footprint.frame_view for a kind with FOOTPRINT, else footprint.OFF (unused)."""
    return frame_view(basis, width, height) if FOOTPRINT else OFF


@numba.njit(inline="always")
def _place(x0, y0, end_row, width):
    """The packet at (x0, y0)'s first and last pixels' columns and rows, footprint.window_of's place."""
    return x0, y0, min(x0 + PACKET_W, width) - 1, min(y0 + PACKET_H, end_row) - 1


@compiled.njit(nogil=True, error_model="numpy")
def _bvh_packets_wide(first_row, end_row, width, height, basis, wide, wide_links, ordered, order, spheres, image,
                      hits, stop):  # fmt: skip
    """The rows first_row..end_row, a PACKET_W x PACKET_H packet of rays at
    a time through the 4-wide tree (bvh.collapse), each packet started
    (_start_packet), walked (_packet_walk_wide) and shaded (_store_packet);
    with FOOTPRINT, one outside the tree's footprint (footprint.tree_window)
    only shaded, as the background. Each ray gets the nearest primitive of
    all it could hit, ties to the smaller index."""
    stack_row = np.empty(WIDE_STACK, np.int32)
    stack_count = np.empty(WIDE_STACK, np.int32)
    dx = np.empty(PACKET, np.float32)
    dy = np.empty(PACKET, np.float32)
    dz = np.empty(PACKET, np.float32)
    ix = np.empty(PACKET, np.float32)
    iy = np.empty(PACKET, np.float32)
    iz = np.empty(PACKET, np.float32)
    closest = np.empty(PACKET, np.float32)
    spread = np.empty(7, np.float32)
    closest_bits, spread_bits = closest.view(np.int32), spread.view(np.int32)
    hit = np.empty(PACKET, np.int32)
    hit_d = np.empty(PACKET, np.float32)
    rgb = np.empty((3, PACKET), np.uint8)
    paint = np.empty((4, PACKET), np.float32)
    along = np.empty(WIDTH, np.float32)
    scratch = np.empty((SCRATCH, PACKET + 1), np.float32)
    lanes = np.zeros((LEAF_ROWS, 2 * LEAF_LANES), np.float32)
    ox, oy, oz = basis[0, 0], basis[0, 1], basis[0, 2]
    margin = (abs(ox) + abs(oy) + abs(oz)) * PAD
    view = _frame_view(basis, width, height)
    # with FOOTPRINT, a packet outside the band's pixels whose rays can meet the tree is the background's, its
    # rays never made (docs/notes/embree.md#packets-outside-the-trees-footprint-2026-12-06)
    r0, r1, c0, c1 = tree_window(view, wide, wide_links, (0, first_row, width - 1, end_row - 1), end_row - first_row,
                                 width, margin, ox, oy, oz)  # fmt: skip
    for y0 in range(first_row, end_row, PACKET_H):
        if stop[0]:
            return
        off_rows = y0 + PACKET_H <= first_row + r0 or y0 >= first_row + r1
        for x0 in range(0, width, PACKET_W):
            if FOOTPRINT and (off_rows or x0 + PACKET_W <= c0 or x0 >= c1):
                hit[:] = -1
                hit_d[:] = ZERO
            else:
                _start_packet(x0, y0, end_row, width, height, basis, dx, dy, dz, ix, iy, iz, closest, hit, hit_d,
                              spread)  # fmt: skip
                if FOOTPRINT:
                    scratch[3, PACKET] = UNAIMED
                _packet_walk_wide(wide, wide_links, ordered, order, ox, oy, oz, margin, dx, dy, dz, ix, iy, iz,
                                  closest, hit, hit_d, spread, closest_bits, spread_bits, stack_row, stack_count,
                                  along, view, _place(x0, y0, end_row, width), scratch, lanes)  # fmt: skip
            _store_packet(x0, y0, end_row, width, spheres, hit, hit_d, rgb, paint, image, hits)
