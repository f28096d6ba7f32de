"""CUDA backend: numba-cuda, in blocks of a chosen shape. With the BVH (accel
"bvh", the default) one thread traces one pixel, walking the tree's nodes
from global memory, either on its own or with the block's other rays as one
packet (walk "ray" or "packet"; by default chosen by the tree's size). Brute
force (accel "none") has two kernels: the simple one is the thesis's, one
thread per pixel; the fast one gives each thread several pixels and stages
the spheres through shared memory.

The per-pixel functions are the same Python source the CPU runs (raybench.kernels),
compiled as CUDA device functions. Under NUMBA_ENABLE_CUDASIM=1 it runs in
numba's simulator, which is how the tests check it on machines without a GPU.

  device   whether numba-cuda finds a device here
  tracer   the Tracer and its kernels
  build    the LBVH built on the GPU (build="gpu")
  launch   launches with their arguments converted once
  kinds    the kernels of another kind of primitive (a mesh's triangles):
           these modules compiled again over its answers
"""

from __future__ import annotations

from ..options import DEFAULT_BLOCK
from .device import available, description, require, simulated, unavailable_reason
from .tracer import Tracer

__all__ = ["DEFAULT_BLOCK", "Tracer", "available", "description", "require", "simulated", "unavailable_reason"]
