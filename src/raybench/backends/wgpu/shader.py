"""The WGSL compute shader, assembled from its pieces.

The pieces port the single-source kernels (raybench.kernels) function by
function: common.wgsl (bindings), intersect.wgsl, shade.wgsl, trace.wgsl (the
primary ray, the pixel, the entry point), and one nearest_hit per
acceleration structure: brute.wgsl, the thesis's loop over every sphere. A BVH
traversal would be one more piece with the same nearest_hit signature, picked
by the accel option, and its own bindings.
"""

from __future__ import annotations

import functools
from importlib import resources

from ...errors import RaybenchError

ACCELS = {"none": "brute.wgsl"}
PIECES = ("common.wgsl", "intersect.wgsl", "shade.wgsl", "trace.wgsl")


@functools.cache
def _piece(name: str) -> str:
    return resources.files(__package__).joinpath(name).read_text(encoding="utf-8")


def check_accel(accel) -> str:
    if accel not in ACCELS:
        raise RaybenchError(f"accel: the wgpu backend has {', '.join(map(repr, ACCELS))} only (brute force, the "
                            f"thesis's loop), got {accel!r}")
    return accel


def source(workgroup: tuple[int, int], accel: str = "none") -> str:
    """The whole shader for one workgroup shape (a compile-time constant in
    WGSL) and acceleration structure."""
    parts = [_piece(p) for p in PIECES] + [_piece(ACCELS[check_accel(accel)])]
    text = "\n".join(parts)
    return text.replace("WORKGROUP_X", f"{workgroup[0]}u").replace("WORKGROUP_Y", f"{workgroup[1]}u")
