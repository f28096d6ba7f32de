"""THE ray-tracing algorithm, written once in plain Python.

build(jit) compiles it with the given decorator: numba.njit for the CPU,
numba.cuda.jit(device=True) for NVIDIA GPUs. There is no other copy of the
intersection or shading code; the backends only decide how pixels map to threads.
"""

from .trace import build

__all__ = ["build"]
