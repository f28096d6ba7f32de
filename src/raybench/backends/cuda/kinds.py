"""cuda's kernels for each kind of primitive (kernels/primitives' KINDS), as
backends/cpu/kinds.py keeps the cpu's.

The sphere's are the modules' own, compiled (or loaded from the cache) at
their first launch: their source and their compiled code are what they were
before any other kind. Another kind's are the same modules compiled again
over its answers (compiled.rebound, which copies numba-cuda's kernels and
device functions with their options): the pixel programs, the voted walk,
the Whitted pixel program, the wavefront's stages and the GPU builder's
kernels that read a primitive (its extent and copy_leaf), so a process can
hold a sphere scene's kernels and a mesh's side by side. They are not in
numba-cuda's disk cache: a mesh's first frame in each process compiles them.
"""

from __future__ import annotations

import functools
from types import SimpleNamespace

from ... import compiled
from ...kernels.primitives import KINDS, sphere
from . import build, program, wavefront

# They call none of one another's kernels; each is copied over its own globals.
MODULES = (program, wavefront, build)


@functools.cache
def programs(kind: str) -> SimpleNamespace:
    """The kernels a cuda Tracer launches for a kind of primitive (a name of
    KINDS, checked by backends.tracer): `program` (the frame's kernels and
    fast_kernel, _constant_kernel), `wavefront` (its _stages, sphere_rows
    and _made), `build` (Builder's kind: its kernels and the primitive) and
    `primitive`, the kind's module."""
    primitive = KINDS[kind]
    spaces = compiled.per_kind(MODULES, primitive, sphere)
    kernels = spaces["build"]._kernels()
    kernels.primitive = primitive  # a copy's module names the sphere's: the kind is this one
    return SimpleNamespace(
        program=spaces["program"],
        wavefront=spaces["wavefront"],
        stages=spaces["wavefront"]._stages(),
        build=kernels,
        primitive=primitive,
    )
