"""CPU backend: the image cut into equal bands of rows, one band per thread.

This is the thesis's own scheme ("divided up into eight threads, which each
process an equal amount of pixels"): any thread count from 1 to one per row,
each thread running the compiled kernel on its band with the GIL released.
Two kernels: "simple", the thesis's loop a pixel at a time, and "fast", which
runs a SIMD cull test over groups of spheres before the exact test (same pixels).

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
from ..kernels.trace import FAR, ZERO
from ..errors import RaybenchError
from .limits import HOST_PIXEL_BYTES, check_count, check_fits, check_kernel, host_available_bytes

MAX_THREADS = 4096

_k = kernels.build(numba.njit(inline="always"))
# module globals, which is how jitted code can see them
_render_pixel, _primary_ray, _store_pixel = _k.render_pixel, _k.primary_ray, _k.store_pixel
_prepare_one, _may_hit, _intersect_relative = _k.prepare, _k.may_hit, _k.intersect_relative

# Spheres per cull group in the fast kernels: a group's cull test is one
# loop that LLVM turns into SIMD. 32 measured fastest on a 2-core EPYC
# (16: 1.6, 32: 2.8, 48: 1.0 G tests/s a thread; 48 did not vectorise).
GROUP = 32
# Rays side by side in the AVX-512 kernel: one 16-lane register of float32.
WIDE = 16

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


@numba.njit(nogil=True)
def _prepare(basis, spheres, count, relative):
    for i in range(count):
        _prepare_one(i, basis, spheres, relative)


@numba.njit(nogil=True)
def _pairs_band(first_row, end_row, width, height, basis, spheres, relative, count, image, hits):
    """The fast kernel for AVX2 and narrower: the rows of a band two pixels at
    a time, the spheres GROUP at a time. The cull test of a whole group on
    both rays is one SIMD loop across the spheres (each sphere's EO loaded
    once for two rays), and only a group it cannot rule out is walked again,
    sphere by sphere, with the exact test. Same arithmetic, same order of
    spheres, same pixels as _render_band."""
    ex, ey, ez, es = relative[0], relative[1], relative[2], relative[3]
    radius = spheres[3]
    for y in range(first_row, end_row):
        for x in range(0, width, 2):
            x1 = min(x + 1, width - 1)  # an odd width traces its last pixel twice, stores it once
            ax, ay, az = _primary_ray(x, y, width, height, basis)
            bx, by, bz = _primary_ray(x1, y, width, height, basis)
            a_closest, a_hit, a_d = FAR, -1, ZERO
            b_closest, b_hit, b_d = FAR, -1, ZERO
            for first in range(0, count, GROUP):
                end = min(first + GROUP, count)
                maybe = False
                for i in range(first, end):
                    maybe |= _may_hit(ex[i], ey[i], ez[i], es[i], ax, ay, az) | \
                        _may_hit(ex[i], ey[i], ez[i], es[i], bx, by, bz)
                if maybe:
                    for i in range(first, end):
                        if _may_hit(ex[i], ey[i], ez[i], es[i], ax, ay, az):
                            t, d = _intersect_relative(ex[i], ey[i], ez[i], radius[i], ax, ay, az)
                            if t < a_closest and t > ZERO:
                                a_closest, a_hit, a_d = t, i, d
                        if _may_hit(ex[i], ey[i], ez[i], es[i], bx, by, bz):
                            t, d = _intersect_relative(ex[i], ey[i], ez[i], radius[i], bx, by, bz)
                            if t < b_closest and t > ZERO:
                                b_closest, b_hit, b_d = t, i, d
            _store_pixel(x, y, a_hit, a_d, spheres, image, hits)
            if x1 > x:
                _store_pixel(x1, y, b_hit, b_d, spheres, image, hits)


@numba.njit(nogil=True)
def _wide_band(first_row, end_row, width, height, basis, spheres, relative, count, image, hits):
    """The fast kernel for AVX-512: WIDE pixels of a row side by side, so the
    cull test of each sphere is one SIMD compare across the rays; a group of
    GROUP spheres is walked again with the exact test only where some ray
    may hit one of them. Same arithmetic, same order, same pixels."""
    ex, ey, ez, es = relative[0], relative[1], relative[2], relative[3]
    radius = spheres[3]
    dx = np.empty(WIDE, np.float32)
    dy = np.empty(WIDE, np.float32)
    dz = np.empty(WIDE, np.float32)
    closest = np.empty(WIDE, np.float32)
    hit = np.empty(WIDE, np.int64)
    hit_d = np.empty(WIDE, np.float32)
    for y in range(first_row, end_row):
        for x in range(0, width, WIDE):
            for k in range(WIDE):  # pixels past the edge trace a copy of the last one, unstored
                dx[k], dy[k], dz[k] = _primary_ray(min(x + k, width - 1), y, width, height, basis)
                closest[k], hit[k], hit_d[k] = FAR, -1, ZERO
            for first in range(0, count, GROUP):
                end = min(first + GROUP, count)
                maybe = False
                for i in range(first, end):
                    for k in range(WIDE):
                        maybe |= _may_hit(ex[i], ey[i], ez[i], es[i], dx[k], dy[k], dz[k])
                if maybe:
                    for i in range(first, end):
                        for k in range(WIDE):
                            if _may_hit(ex[i], ey[i], ez[i], es[i], dx[k], dy[k], dz[k]):
                                t, d = _intersect_relative(ex[i], ey[i], ez[i], radius[i], dx[k], dy[k], dz[k])
                                if t < closest[k] and t > ZERO:
                                    closest[k], hit[k], hit_d[k] = t, i, d
            for k in range(min(WIDE, width - x)):
                _store_pixel(x + k, y, hit[k], hit_d[k], spheres, image, hits)


def _has_avx512() -> bool:
    """Whether the CPU Numba compiles for has 16-lane float32 registers."""
    try:
        from llvmlite import binding
        return bool(binding.get_host_cpu_features().get("avx512f", False))
    except Exception:  # an llvmlite without the query: the kernel that suits every CPU
        return False


# Which loop vectorises best depends on the register width: on the H100
# machine's AVX-512 Xeon (16 threads) the wide kernel takes 90 ms a frame
# against 185 ms for the pairs kernel; on a 2-core AVX2 EPYC the pairs kernel
# is the faster by 20% (docs/performance.md).
_fast_band = _wide_band if _has_avx512() else _pairs_band


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
                 constant_count: bool = False, kernel: str = "fast"):
        self.kernel = check_kernel(kernel, constant_count)
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
        if self.kernel == "fast":
            self._kernel = _fast_band
            self.relative = np.zeros((4, self.count), np.float32)
        else:
            self._kernel = _constant_band(self.count) if self.constant_count else _render_band

    def _args(self, basis, count):
        if self.kernel == "fast":
            _prepare(basis, self.spheres, count, self.relative)
            return (self.width, self.height, basis, self.spheres, self.relative, count, self.image, self.hits)
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

