"""CUDA backend: numba-cuda, one thread per pixel, in blocks of a chosen shape.

The per-pixel program is the same Python source the CPU runs (raybench.kernels),
compiled as CUDA device functions. Under NUMBA_ENABLE_CUDASIM=1 it runs in
numba's simulator, which is how the tests check it on machines without a GPU.
"""

from __future__ import annotations

import functools
import math
import time
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


@functools.lru_cache(maxsize=None)
def _constant_kernel(count: int):
    """_render_kernel with the sphere count frozen into the code (a compile-time
    constant, as in the thesis's tests 1 to 6); one compilation per count."""

    @cuda.jit
    def render_kernel(width, height, basis, spheres, _count, image, hits):
        x, y = cuda.grid(2)
        if x < width and y < height:
            _render_pixel(x, y, width, height, basis, spheres, count, image, hits)

    return render_kernel


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

    def __init__(self, spheres: np.ndarray, width: int, height: int, block=DEFAULT_BLOCK,
                 constant_count: bool = False):
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
        self.d_basis = cuda.device_array((4, 3), dtype=np.float32)
        self.constant_count = bool(constant_count)
        self._kernel = _constant_kernel(self.count) if self.constant_count else _render_kernel

    def compile(self) -> float:
        """Compile the kernel if needed (one empty launch); the seconds it took."""
        start = time.perf_counter()
        self._launch((1, 1), 0, 0, self.count)
        cuda.synchronize()
        return time.perf_counter() - start

    def _launch(self, grid, width, height, count) -> None:
        with warnings.catch_warnings():
            # Small frames cannot fill the GPU; that is the user's choice, not news.
            warnings.simplefilter("ignore", NumbaPerformanceWarning)
            self._kernel[grid, self.block](width, height, self.d_basis, self.d_spheres, count,
                                           self.d_image, self.d_hits)

    def _prepare(self, basis: np.ndarray, count: int | None) -> int:
        """Upload the camera; the sphere count to trace."""
        self.d_basis.copy_to_device(basis)
        return self.count if count is None else check_count(count, self.count, self.constant_count)

    def launch(self, basis: np.ndarray, count: int | None = None) -> None:
        """Start the kernel for one frame of the first `count` spheres (default
        all); it runs asynchronously."""
        self._launch(self.grid, self.width, self.height, self._prepare(basis, count))

    def fetch(self) -> tuple[np.ndarray, np.ndarray]:
        """Copy the last frame to the host (waits for the kernel)."""
        self.d_image.copy_to_host(self.image)
        self.d_hits.copy_to_host(self.hits)
        return self.image, self.hits

    def trace(self, basis: np.ndarray, count: int | None = None) -> tuple[np.ndarray, np.ndarray]:
        self.launch(basis, count)
        return self.fetch()

    def timed_trace(self, basis: np.ndarray, count: int | None = None) -> float:
        """trace(), returning the kernel's own time in ms (CUDA events around the
        launch alone; the camera upload and the copy back are outside). None
        under the simulator, which has no GPU clock to read."""
        if simulated():
            self.trace(basis, count)
            return None
        count = self._prepare(basis, count)
        start, end = cuda.event(), cuda.event()
        start.record()
        self._launch(self.grid, self.width, self.height, count)
        end.record()
        self.fetch()
        end.synchronize()
        return start.elapsed_time(end)

    def close(self) -> None:
        """Device buffers go with the object; nothing to release by hand."""
