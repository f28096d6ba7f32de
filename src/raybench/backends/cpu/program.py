"""The CPU's pixel programs: kernels.build compiled for this backend, with
the CPU's packets of shadow rays and its search of the 4-wide tree."""

import numba
import numpy as np

from ... import kernels
from ...kernels.shadow_packets import (
    _T_CLOSEST,
    _T_HIT,
    _T_HIT_D,
    _T_LANE,
    _T_S_COUNT,
    _T_S_REF,
    _T_S_T,
    _T_WIDE,
    _T_WIDE_LINKS,
    _packet_shadows,
)
from ...kernels.wide_walk import _walk_wide


@numba.njit(inline="always")
def _search_wide(ox, oy, oz, dx, dy, dz, t_max, any_hit, own, own_inside, spheres, count, tree, stack_row, stack_t):
    """The packets program's search (trace.search_tree's signature): a
    primary ray (the one ray that leaves no sphere, own < 0) reads its hit
    from its tile's packet, walked before the tile's pixels are shaded; the
    reflected and refracted rays walk the 4-wide tree alone (_walk_wide)."""
    if own < 0:
        k = tree[_T_LANE][0]
        return np.int64(tree[_T_HIT][k]), tree[_T_CLOSEST][k], tree[_T_HIT_D][k]
    return _walk_wide(ox, oy, oz, dx, dy, dz, t_max, any_hit, own, own_inside, tree[_T_WIDE], tree[_T_WIDE_LINKS],
                      tree[2], tree[3], tree[_T_S_REF], tree[_T_S_COUNT], tree[_T_S_T])  # fmt: skip


# find, the one call of the Whitted programs through the binary tree and by
# brute force, is compiled without the runtime's reference counting
# (_nrt=False; _whitted_tiles says why): it allocates nothing and keeps no
# array. The packets program inlines its find (trace.build).
_k = kernels.build(
    numba.njit(inline="always"),
    call=numba.njit(nogil=True, _nrt=False),
    shadows=_packet_shadows,
    packets_search=_search_wide,
)
# module globals, which is how jitted code can see them
_render_pixel, _primary_ray, _store_pixel = _k.render_pixel, _k.primary_ray, _k.store_pixel
_prepare_one, _may_hit, _intersect_relative = _k.prepare, _k.may_hit, _k.intersect_relative
