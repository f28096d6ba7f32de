"""The CPU's Whitted rows: a band of rows a call, a pixel at a time through
the binary tree or by brute force, or a tile at a time through the 4-wide
tree with the primary and shadow rays as packets."""

import numba
import numpy as np

from ... import compiled, layout
from ...kernels import whitted as whitted_mod
from ...kernels.packets import (
    LEAF_LANES,
    LEAF_ROWS,
    PACKET,
    PACKET_H,
    PACKET_W,
    SCRATCH,
    _frame_view,
    _kind_constants,  # noqa: F401 - a kind's copy tiles by its packets (compiled.rebound)
    _packet_walk_ahead,
    _place,
    _start_packet,
)
from ...kernels.shadow_packets import BLOCKER_SLOTS, LANES, PacketsTree
from ...layout import (
    PAD,
    STACK,
    WIDE_STACK,
    WIDTH,
)
from .program import _k


@numba.njit(inline="always")
def _whitted_rows(render_pixel, first_row, end_row, width, height, basis, spheres, count, materials, lights, pattern,
                  params, tree, image, hits, counts, stop):  # fmt: skip
    """Whitted shading of the rows first_row..end_row with render_pixel (the
    program through the binary tree, or by brute force), a pixel at a time,
    every ray alone; counts[y]: the rays row y cast, by kind. The packets
    program has its own loop (_whitted_tiles)."""
    stack_row = np.empty(STACK, np.int32)
    stack_t = np.empty(STACK, np.float32)
    rays_f = np.empty((whitted_mod.RAY_STACK, whitted_mod.RAY_FLOATS), np.float32)
    rays_i = np.empty((whitted_mod.RAY_STACK, whitted_mod.RAY_INTS), np.int32)
    for y in range(first_row, end_row):
        if stop[0]:
            return
        primary = shadow = reflection = refraction = 0
        for x in range(width):
            a, b, c, d = render_pixel(
                x, y, width, height, basis, spheres, count, materials, lights, pattern, params, tree, stack_row,
                stack_t, rays_f, rays_i, image, hits,
            )  # fmt: skip
            primary += a
            shadow += b
            reflection += c
            refraction += d
        counts[y, layout.PRIMARY] = primary
        counts[y, layout.SHADOW] = shadow
        counts[y, layout.REFLECTION] = reflection
        counts[y, layout.REFRACTION] = refraction


_whitted_bvh_pixel, _whitted_all_pixel = _k.render_pixel_whitted["bvh"], _k.render_pixel_whitted["none"]


# One cached kernel for each search, written out at module level: a kernel
# that a factory makes, closing over the pixel program, misses Numba's cache
# in every new process (tried: each run added an index entry, none was hit).
@compiled.njit(nogil=True)
def _whitted_rows_bvh(first_row, end_row, width, height, basis, spheres, count, materials, lights, pattern, params,
                      tree, image, hits, counts, stop):  # fmt: skip
    _whitted_rows(_whitted_bvh_pixel, first_row, end_row, width, height, basis, spheres, count, materials, lights,
                  pattern, params, tree, image, hits, counts, stop)  # fmt: skip


@compiled.njit(nogil=True)
def _whitted_rows_all(first_row, end_row, width, height, basis, spheres, count, materials, lights, pattern, params,
                      tree, image, hits, counts, stop):  # fmt: skip
    _whitted_rows(_whitted_all_pixel, first_row, end_row, width, height, basis, spheres, count, materials, lights,
                  pattern, params, tree, image, hits, counts, stop)  # fmt: skip


_whitted_packets_pixel = _k.render_pixel_whitted["packets"]


@compiled.njit(nogil=True)
def _whitted_rows_packets(first_row, end_row, width, height, basis, spheres, count, materials, lights, pattern,
                          params, tree, image, hits, counts, stop):  # fmt: skip
    """Whitted shading of the rows first_row..end_row (a multiple of
    PACKET_H from the frame's top) through the 4-wide tree (_whitted_tiles),
    given the thread's scratch; tree: (nodes, links, ordered, order, wide,
    wide_links)."""
    nodes, links, ordered, order, wide, wide_links = tree
    lanes = np.empty((7, PACKET), np.float32)
    hit = np.empty(PACKET, np.int32)
    own = PacketsTree(nodes, links, ordered, order, wide, wide_links, np.empty((7, LANES), np.float32),
                      np.empty(7, np.float32), np.empty(WIDE_STACK, np.int32), np.empty(WIDTH, np.float32), hit,
                      lanes[6], np.empty(PACKET, np.float32), np.zeros(1, np.int64), np.empty(WIDE_STACK, np.int32),
                      np.empty(WIDE_STACK, np.int32), np.empty(WIDE_STACK, np.float32),
                      np.full(BLOCKER_SLOTS, -1, np.int32))  # fmt: skip
    _whitted_tiles(
        first_row, end_row, width, height, basis, spheres, count, materials, lights, pattern, params, own, lanes,
        np.empty(7, np.float32), np.empty(WIDE_STACK, np.int32), np.empty(WIDE_STACK, np.int32),
        np.empty(WIDTH, np.float32), np.empty((SCRATCH, PACKET + 1), np.float32),
        np.zeros((LEAF_ROWS, 2 * LEAF_LANES), np.float32), np.empty(STACK, np.int32),
        np.empty(STACK, np.float32), np.empty((whitted_mod.RAY_STACK, whitted_mod.RAY_FLOATS), np.float32),
        np.empty((whitted_mod.RAY_STACK, whitted_mod.RAY_INTS), np.int32), image, hits, counts, stop,
    )  # fmt: skip


# Without the runtime's reference counting (_nrt=False): Numba counts the
# references to every array each time one is passed to a function, inlined
# or not, or taken from a tuple, with an atomic add and subtract on the
# array's shared count (NRT_incref, NRT_decref): in the pixel program, whose
# functions pass the frame's arrays down, those took much of a frame's
# CPU time (perf: docs/notes/whitted.md), and as the threads share the arrays,
# each such add moves a cache line between the cores. These functions
# allocate nothing and keep no array: _whitted_rows_packets, which holds the
# scratch, calls them.
@compiled.njit(nogil=True, error_model="numpy", _nrt=False)
def _tile_primaries(x0, y0, end_row, width, height, basis, wide, wide_links, ordered, order, lanes, hit, hit_d, spread,
                    stack_row, stack_count, along, scratch, leaf_lanes):  # fmt: skip
    """The primary rays of the Whitted frame's PACKET_W x PACKET_H tile at
    (x0, y0) as one packet through the 4-wide tree (_bvh_packets_wide's
    walk, with the Whitted rays' test): lanes[6] (their t, FAR where none),
    hit and hit_d, the answer of traverse.walk for each ray alone. lanes[:6]:
    directions and inverses; scratch: the packet's (packets.SCRATCH rows),
    whose rays' aim these, tested with hit_ahead_from, leave alone;
    leaf_lanes: a leaf's primitives side by side (packets.LEAF_LANES). A call of its own, with
    NumPy's error model, which leaves the packet's loops SIMD (_kb's
    note)."""
    closest = lanes[6]
    dx, dy, dz, ix, iy, iz = lanes[0], lanes[1], lanes[2], lanes[3], lanes[4], lanes[5]
    _start_packet(x0, y0, end_row, width, height, basis, dx, dy, dz, ix, iy, iz, closest, hit, hit_d, spread)
    ox, oy, oz = basis[0, 0], basis[0, 1], basis[0, 2]
    margin = (abs(ox) + abs(oy) + abs(oz)) * PAD
    _packet_walk_ahead(wide, wide_links, ordered, order, ox, oy, oz, margin, dx, dy, dz, ix, iy, iz, closest, hit,
                       hit_d, spread, closest.view(np.int32), spread.view(np.int32), stack_row, stack_count, along,
                       _frame_view(basis, width, height), _place(x0, y0, end_row, width), scratch,
                       leaf_lanes)  # fmt: skip


@compiled.njit(nogil=True, _nrt=False)
def _whitted_tiles(first_row, end_row, width, height, basis, spheres, count, materials, lights, pattern, params, tree,
                   lanes, spread, packet_row, packet_count, along, scratch, leaf_lanes, stack_row, stack_t, rays_f,
                   rays_i, image, hits, counts, stop):  # fmt: skip
    """_whitted_rows_packets' work, a tile of PACKET_W x PACKET_H pixels at
    a time: the tile's primary rays as one packet (_tile_primaries), then
    each pixel's program, whose reflected and refracted rays walk the wide
    tree alone (_search_wide) and whose shadow rays to a light go as packets
    (_packet_shadows); counts[y]: the rays row y cast, by kind."""
    wide, wide_links, ordered, order = tree.wide, tree.wide_links, tree.ordered, tree.order
    hit, hit_d, lane = tree.hit, tree.hit_d, tree.lane
    for y0 in range(first_row, end_row, PACKET_H):
        if stop[0]:
            return
        lines = min(PACKET_H, end_row - y0)
        for y in range(y0, y0 + lines):
            for kind in range(len(layout.KINDS)):
                counts[y, kind] = 0
        for x0 in range(0, width, PACKET_W):
            _tile_primaries(x0, y0, end_row, width, height, basis, wide, wide_links, ordered, order, lanes, hit, hit_d,
                            spread, packet_row, packet_count, along, scratch, leaf_lanes)  # fmt: skip
            for line in range(lines):
                y = y0 + line
                for i in range(min(PACKET_W, width - x0)):
                    lane[0] = line * PACKET_W + i
                    a, b, c, d = _whitted_packets_pixel(
                        x0 + i, y, width, height, basis, spheres, count, materials, lights, pattern, params, tree,
                        stack_row, stack_t, rays_f, rays_i, image, hits,
                    )  # fmt: skip
                    counts[y, layout.PRIMARY] += a
                    counts[y, layout.SHADOW] += b
                    counts[y, layout.REFLECTION] += c
                    counts[y, layout.REFRACTION] += d


WHITTED_ROWS = {"bvh": _whitted_rows_bvh, "none": _whitted_rows_all, "packets": _whitted_rows_packets}
