"""wgpu backend: the algorithm as a WGSL compute shader, on Vulkan, Metal or
D3D12 through wgpu, one invocation per pixel in workgroups of a chosen shape.

The shader (the .wgsl pieces here, assembled by shader.py) is a port of the
single-source kernels in raybench.kernels, brute force and the BVH walk, held
to the same pictures by the tests. adapters.py picks the adapter (a GPU
unless a CPU driver is named), compute.py records the compute pass on any
device (the viewer's too, for its copy-free path) and builds the BVH,
tracer.py is the Tracer with the readback.

Nothing here imports wgpu until an adapter is asked for.
"""

from __future__ import annotations

from ..options import DEFAULT_WORKGROUP
from .adapters import choose, found, gpu_present
from .tracer import Tracer

__all__ = ["DEFAULT_WORKGROUP", "Tracer", "choose", "description", "found", "gpu_present", "require"]


def require(adapter: str | None = None) -> None:
    """A RaybenchError, in one line, unless an adapter is there to trace on."""
    choose(adapter)


def description(adapter: str | None = None) -> str:
    return f"wgpu ({choose(adapter).label()})"
