"""CPU backend: Numba, image rows spread over all cores.

fastmath stays off: the float32 arithmetic is then exactly IEEE, so the CPU image
is bit-identical to the CUDA kernel run under numba's simulator, and the tests
can hold the two to equality rather than to a tolerance.
"""

from __future__ import annotations

import numba
import numpy as np

from .. import kernels
from ..errors import RaybenchError
from .memory import check_fits

_render_pixel = kernels.build(numba.njit(inline="always"))


@numba.njit(parallel=True)
def _render_rows(width, height, basis, spheres, count, image, hits):
    for y in numba.prange(height):
        for x in range(width):
            _render_pixel(x, y, width, height, basis, spheres, count, image, hits)


def max_threads() -> int:
    return numba.config.NUMBA_NUM_THREADS


def description() -> str:
    return f"cpu ({max_threads()} threads, Numba {numba.__version__})"


class Tracer:
    """Renders one scene at one size, frame after frame."""

    name = "cpu"

    def __init__(self, spheres: np.ndarray, width: int, height: int, threads: int | None = None):
        if threads is None:
            threads = max_threads()
        if isinstance(threads, bool) or not isinstance(threads, (int, np.integer)) or not 1 <= threads <= max_threads():
            raise RaybenchError(f"threads: must be an integer from 1 to {max_threads()} (the size of Numba's thread pool; "
                                f"set NUMBA_NUM_THREADS for more), got {threads!r}")
        check_fits("cpu", width, height, spheres.shape[1], available_bytes())
        self.threads = int(threads)
        self.spheres = spheres
        self.width, self.height = width, height
        self.image = np.empty((height, width, 3), dtype=np.uint8)
        self.hits = np.empty((height, width), dtype=np.int32)

    def trace(self, basis: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Trace a frame into self.image and self.hits (reused between frames)."""
        numba.set_num_threads(self.threads)
        _render_rows(self.width, self.height, basis, self.spheres, self.spheres.shape[1], self.image, self.hits)
        return self.image, self.hits


def available_bytes() -> int:
    import psutil

    return psutil.virtual_memory().available
