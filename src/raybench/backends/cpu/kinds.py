"""The CPU's kernels for each kind of primitive (kernels/primitives' KINDS).

The sphere's are the modules' own, compiled (or loaded from the cache) as
they are imported. Another kind's are the same modules compiled again over
its answers (compiled.rebound): the packets, the shadow packets, the
4-wide single-ray walk, the pixel programs, brute force and Whitted's rows,
each calling the others' copies, so a process can hold a sphere scene's
kernels and a mesh's side by side. They are in raybench's disk cache, filed
under the kind's name as well (compiled.rebound): the first mesh a machine
traces compiles them, and later processes load them.
"""

from __future__ import annotations

import functools
from types import SimpleNamespace

from ... import compiled
from ...errors import RaybenchError
from ...kernels import packets, shadow_packets, tree_leaves, wide_walk
from ...kernels.primitives import KINDS, sphere
from . import brute, program, whitted_rows

# In the order they import one another: each module's copy calls the copies
# of those before it.
MODULES = (tree_leaves, packets, shadow_packets, wide_walk, program, brute, whitted_rows)


def primitive_of(kind: str):
    """The module of kernels/primitives for a kind's name, or one line naming the kinds."""
    if not isinstance(kind, str) or kind not in KINDS:
        raise RaybenchError(f"primitive: must be one of {', '.join(KINDS)}, got {kind!r}")
    return KINDS[kind]


@functools.cache
def programs(kind: str) -> SimpleNamespace:
    """The kernels the Tracer runs for a kind of primitive: packets
    (_bvh_packets_wide), rows (_bvh_rows, the binary tree), whitted (the
    Whitted rows by walk: WHITTED_ROWS), and brute force's render_band,
    constant_band, fast_band and prepare (the last two the sphere's only:
    None for a kind without a cull)."""
    primitive = primitive_of(kind)
    spaces = compiled.per_kind(MODULES, primitive, sphere, cached=True)
    culls = primitive is sphere
    return SimpleNamespace(
        packets=spaces["packets"]._bvh_packets_wide,
        rows=spaces["program"]._bvh_rows,
        whitted=spaces["whitted_rows"].WHITTED_ROWS,
        render_band=spaces["brute"]._render_band,
        constant_band=spaces["brute"]._constant_band,
        fast_band=spaces["brute"]._fast_band if culls else None,
        prepare=spaces["brute"]._prepare if culls else None,
    )
