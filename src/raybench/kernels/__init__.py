"""THE ray-tracing algorithm, written once in plain Python.

make(jit) compiles it with the given decorator (numba.njit for the CPU,
numba.cuda.jit(device=True) for NVIDIA GPUs) and returns its functions. There
is no other copy of the intersection or shading code; the backends only decide
how pixels map to threads and, in the fast kernels, how rays and spheres are
grouped.
"""

from .trace import make

__all__ = ["make"]
