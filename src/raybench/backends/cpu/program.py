"""The CPU's pixel programs: kernels.make compiled for this backend, with
the CPU's packets of shadow rays and its search of the 4-wide tree."""

import functools

import numba
import numpy as np

from ... import compiled, kernels
from ...kernels.primitives import sphere
from ...kernels.shadow_packets import _packet_shadows
from ...kernels.wide_walk import _walk_wide
from ...layout import STACK


@numba.njit(inline="always")
def _search_wide(ox, oy, oz, dx, dy, dz, t_max, any_hit, own, own_inside, spheres, count, tree, stack_row, stack_t):
    """The packets program's search (trace.search_tree's signature): a
    primary ray (the one ray that leaves no sphere, own < 0) reads its hit
    from its tile's packet, walked before the tile's pixels are shaded; the
    reflected and refracted rays walk the 4-wide tree alone (_walk_wide)."""
    if own < 0:
        k = tree.lane[0]
        return np.int64(tree.hit[k]), tree.closest[k], tree.hit_d[k]
    return _walk_wide(ox, oy, oz, dx, dy, dz, t_max, any_hit, own, own_inside, tree.wide, tree.wide_links,
                      tree.ordered, tree.order, tree.s_ref, tree.s_count, tree.s_t)  # fmt: skip


# find, the one call of the Whitted programs through the binary tree and by
# brute force, is compiled without the runtime's reference counting
# (_nrt=False; _whitted_tiles says why): it allocates nothing and keeps no
# array. The packets program inlines its find (trace.make).
# Made for a primitive, the sphere's at import; compiled.rebound compiles
# this module again for another kind (backends/cpu/kinds.py).
@functools.cache
def _made(primitive=sphere):
    """kernels.make for this backend, for one kind of primitive."""
    return kernels.make(
        numba.njit(inline="always"),
        call=numba.njit(nogil=True, _nrt=False),
        shadows=_packet_shadows,
        packets_search=_search_wide,
        primitive=primitive,
    )


_k = _made()
# module globals, which is how jitted code can see them
_render_pixel, _primary_ray, _store_pixel = _k.render_pixel, _k.primary_ray, _k.store_pixel
# the primitive's own answers (kernels/primitives), as the kernels call them
_prepare_one, _may_hit = _k.prepare, _k.prim.may_hit
_read, _seen_from, _hit_from = _k.prim.read, _k.prim.seen_from, _k.prim.hit_from
_render_pixel_bvh = _k.render_pixel_bvh


@compiled.njit(nogil=True)
def _bvh_rows(first_row, end_row, width, height, basis, nodes, links, ordered, order, spheres, image, hits, stop):
    """The thesis's rows first_row..end_row through the binary tree, a pixel
    at a time, every ray alone by kernels.traverse's walk: the GPUs' own
    walk, on the CPU (tree_width 2). The arguments of _bvh_packets_wide."""
    stack_row = np.empty(STACK, np.int32)
    stack_t = np.empty(STACK, np.float32)
    for y in range(first_row, end_row):
        if stop[0]:
            return
        for x in range(width):
            _render_pixel_bvh(x, y, width, height, basis, nodes, links, ordered, order, spheres, image, hits,
                              stack_row, stack_t)  # fmt: skip
