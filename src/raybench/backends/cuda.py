"""CUDA backend: numba-cuda, one thread per pixel, in blocks of a chosen shape.

The per-pixel program is the same Python source the CPU runs (raybench.kernels),
compiled as CUDA device functions. Under NUMBA_ENABLE_CUDASIM=1 it runs in
numba's simulator, which is how the tests check it on machines without a GPU.
"""

from __future__ import annotations

import math
import warnings

import numpy as np
from numba import config, cuda
from numba.cuda.core.errors import NumbaPerformanceWarning

from .. import kernels
from ..errors import RaybenchError
from .limits import HOST_PIXEL_BYTES, check_count, check_fits, host_available_bytes

DEFAULT_BLOCK = (16, 16)

_render_pixel = kernels.build(cuda.jit(device=True))


@cuda.jit
def _render_kernel(width, height, basis, spheres, count, image, hits):
    x, y = cuda.grid(2)
    if x < width and y < height:
        _render_pixel(x, y, width, height, basis, spheres, count, image, hits)


def simulated() -> bool:
    return bool(config.ENABLE_CUDASIM)


def available() -> bool:
    return cuda.is_available()


def unavailable_reason() -> str:
    reason = " ".join((cuda.cuda_error() or "no CUDA device was found").split())
    return f"device cuda: no usable NVIDIA GPU (numba-cuda looked for the CUDA driver and a CUDA device: {reason}); use --device cpu"


def require() -> None:
    if not available():
        raise RaybenchError(unavailable_reason())


def description() -> str:
    require()
    if simulated():
        return "cuda (numba's CUDA simulator)"
    dev = cuda.get_current_device()
    name = dev.name.decode() if isinstance(dev.name, bytes) else dev.name
    return f"cuda ({name})"


def _check_block(block) -> tuple[int, int]:
    try:
        bx, by = (int(v) for v in block)
    except (TypeError, ValueError):
        raise RaybenchError(f"block: must be two integers (x, y), got {block!r}") from None
    if bx < 1 or by < 1 or bx * by > 1024:
        raise RaybenchError(f"block: each side must be >= 1 and x*y at most 1024 threads, got {bx}x{by}")
    return bx, by


class Tracer:
    """Keeps the spheres and the frame buffers on the GPU between frames."""

    name = "cuda"

    def __init__(self, spheres: np.ndarray, width: int, height: int, block=DEFAULT_BLOCK):
        require()
        self.block = _check_block(block)
        free, _total = cuda.current_context().get_memory_info()
        check_fits("cuda GPU", width, height, spheres.shape[1], free)
        check_fits("host", width, height, 0, host_available_bytes(), HOST_PIXEL_BYTES)
        self.width, self.height = width, height
        self.count = spheres.shape[1]
        self.grid = (math.ceil(width / self.block[0]), math.ceil(height / self.block[1]))
        self.d_spheres = cuda.to_device(spheres if self.count else np.zeros((7, 1), np.float32))
        self.d_image = cuda.device_array((height, width, 3), dtype=np.uint8)
        self.d_hits = cuda.device_array((height, width), dtype=np.int32)
        self.image = cuda.pinned_array((height, width, 3), dtype=np.uint8) if not simulated() else \
            np.empty((height, width, 3), np.uint8)
        self.hits = cuda.pinned_array((height, width), dtype=np.int32) if not simulated() else \
            np.empty((height, width), np.int32)

    def launch(self, basis: np.ndarray, count: int | None = None) -> None:
        """Start the kernel for one frame of the first `count` spheres (default
        all); it runs asynchronously."""
        count = self.count if count is None else check_count(count, self.count)
        with warnings.catch_warnings():
            # Small frames cannot fill the GPU; that is the user's choice, not news.
            warnings.simplefilter("ignore", NumbaPerformanceWarning)
            _render_kernel[self.grid, self.block](self.width, self.height, cuda.to_device(basis), self.d_spheres,
                                                  count, self.d_image, self.d_hits)

    def fetch(self) -> tuple[np.ndarray, np.ndarray]:
        """Copy the last frame to the host (waits for the kernel)."""
        self.d_image.copy_to_host(self.image)
        self.d_hits.copy_to_host(self.hits)
        return self.image, self.hits

    def trace(self, basis: np.ndarray, count: int | None = None) -> tuple[np.ndarray, np.ndarray]:
        self.launch(basis, count)
        return self.fetch()

    def close(self) -> None:
        """Device buffers go with the object; nothing to release by hand."""
