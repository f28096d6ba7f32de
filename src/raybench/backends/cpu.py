"""CPU backend: the image cut into equal bands of rows, one band per thread.

This is the thesis's own scheme ("divided up into eight threads, which each
process an equal amount of pixels"): any thread count from 1 to one per row,
each thread running the compiled kernel on its band with the GIL released.

fastmath stays off: the float32 arithmetic is then exactly IEEE, so the CPU image
is bit-identical to the CUDA kernel run under numba's simulator, and the tests
can hold the two to equality rather than to a tolerance.
"""

from __future__ import annotations

import functools
import os
import time
from concurrent.futures import ThreadPoolExecutor

import numba
import numpy as np

from .. import kernels
from ..errors import RaybenchError
from .limits import HOST_PIXEL_BYTES, check_count, check_fits, host_available_bytes

MAX_THREADS = 4096

_render_pixel = kernels.build(numba.njit(inline="always"))


@numba.njit(nogil=True)
def _render_band(first_row, end_row, width, height, basis, spheres, count, image, hits):
    for y in range(first_row, end_row):
        for x in range(width):
            _render_pixel(x, y, width, height, basis, spheres, count, image, hits)


@functools.lru_cache(maxsize=None)
def _constant_band(count: int):
    """_render_band with the sphere count frozen into the code (a compile-time
    constant, as in the thesis's tests 1 to 6); one compilation per count."""

    @numba.njit(nogil=True)
    def render_band(first_row, end_row, width, height, basis, spheres, _count, image, hits):
        for y in range(first_row, end_row):
            for x in range(width):
                _render_pixel(x, y, width, height, basis, spheres, count, image, hits)

    return render_band


def default_threads() -> int:
    return os.cpu_count() or 1


def description() -> str:
    return f"cpu ({default_threads()} threads, Numba {numba.__version__})"


def bands(height: int, threads: int) -> list[tuple[int, int]]:
    """Split rows 0..height into `threads` contiguous bands whose sizes differ by at most one."""
    edges = [height * i // threads for i in range(threads + 1)]
    return [(a, b) for a, b in zip(edges, edges[1:]) if b > a]


class Tracer:
    """Renders one scene at one size, frame after frame, into reused buffers."""

    name = "cpu"

    def __init__(self, spheres: np.ndarray, width: int, height: int, threads: int | None = None,
                 constant_count: bool = False):
        if threads is None:
            threads = default_threads()
        if isinstance(threads, bool) or not isinstance(threads, (int, np.integer)) or not 1 <= threads <= MAX_THREADS:
            raise RaybenchError(f"threads: must be an integer from 1 to {MAX_THREADS}, got {threads!r}")
        check_fits("cpu", width, height, spheres.shape[1], host_available_bytes(), HOST_PIXEL_BYTES)
        self.threads = int(threads)
        self.spheres = spheres
        self.count = spheres.shape[1]
        self.width, self.height = width, height
        self.image = np.empty((height, width, 3), dtype=np.uint8)
        self.hits = np.empty((height, width), dtype=np.int32)
        self.bands = bands(height, self.threads)
        self._pool = ThreadPoolExecutor(len(self.bands)) if len(self.bands) > 1 else None
        self.constant_count = bool(constant_count)
        self._kernel = _constant_band(self.count) if self.constant_count else _render_band

    def _args(self, basis, count):
        return (self.width, self.height, basis, self.spheres, count, self.image, self.hits)

    def compile(self) -> float:
        """Compile the kernel if needed, tracing nothing; the seconds it took."""
        start = time.perf_counter()
        self._kernel(0, 0, *self._args(np.zeros((4, 3), np.float32), self.count))
        return time.perf_counter() - start

    def trace(self, basis: np.ndarray, count: int | None = None) -> tuple[np.ndarray, np.ndarray]:
        """Trace a frame of the first `count` spheres (default all) into
        self.image and self.hits, which are reused between frames."""
        count = self.count if count is None else check_count(count, self.count, self.constant_count)
        args = self._args(basis, count)
        if self._pool is None:
            self._kernel(0, self.height, *args)
        else:
            for job in [self._pool.submit(self._kernel, a, b, *args) for a, b in self.bands]:
                job.result()
        return self.image, self.hits

    def timed_trace(self, basis: np.ndarray, count: int | None = None) -> None:
        """trace(); the CPU has no separate kernel time to report."""
        self.trace(basis, count)
        return None

    def close(self) -> None:
        if self._pool is not None:
            self._pool.shutdown()
            self._pool = None

