"""The CPU's brute-force kernels (accel "none"): the thesis's loop a pixel
at a time ("simple"), and the fast kernels that cull groups of spheres with
SIMD before the exact test ("fast"); the same pixels. A band of rows a call.
Both tests are the primitive's: the cull its prepare and may_hit, the exact
test hit_from on its row seen from the eye (seen_from: the very EO that
prepare computed), so no kernel here reads a sphere's fields.
"""

import functools

import numba
import numpy as np

from ... import compiled
from ...kernels.constants import FAR, ZERO
from .program import _hit_from, _may_hit, _prepare_one, _primary_ray, _read, _render_pixel, _seen_from, _store_pixel

# The cull loops index the spheres with unsigned integers: a signed index
# carries Python's negative-index wraparound, a select per lane that LLVM
# turns into gathers, which slowed the cull (step 5 of
# docs/notes/floors.md#each-version-against-the-floor). The CUDA fast kernel does the
# same for the same reason.
_U = np.uint64
# Spheres per cull group in the fast kernels: a group's cull test is one
# loop that LLVM turns into SIMD. 32 measured fastest: 16 and 64 were slower,
# and 48 did not vectorise (steps 3 and 4 of docs/notes/floors.md#each-version-against-the-floor).
GROUP = 32
# Rays side by side in the AVX-512 kernel: one 16-lane register of float32.
WIDE = 16


@numba.njit(inline="always")
def _band(first_row, end_row, width, height, basis, spheres, count, image, hits, stop):
    """The thesis's rows first_row..end_row, a pixel at a time; the stop
    flag read before each row. Inlined (numba's inlining, before typing),
    so a count frozen by the caller is a constant of its compile."""
    for y in range(first_row, end_row):
        if stop[0]:
            return
        for x in range(width):
            _render_pixel(x, y, width, height, basis, spheres, count, image, hits)


@compiled.njit(nogil=True)
def _render_band(first_row, end_row, width, height, basis, spheres, count, image, hits, stop):
    _band(first_row, end_row, width, height, basis, spheres, count, image, hits, stop)


@functools.cache
def _constant_band(count: int):
    """_render_band with the sphere count frozen into the code (a compile-time
    constant, as in the thesis's tests 1 to 6); one compilation per count."""

    @numba.njit(nogil=True)
    def render_band(first_row, end_row, width, height, basis, spheres, _count, image, hits, stop):
        _band(first_row, end_row, width, height, basis, spheres, count, image, hits, stop)

    return render_band


@compiled.njit(nogil=True)
def _prepare(basis, spheres, count, relative):
    for i in range(count):
        _prepare_one(i, basis, spheres, relative)


@compiled.njit(nogil=True)
def _pairs_band(first_row, end_row, width, height, basis, spheres, relative, count, image, hits, stop):
    """The fast kernel for AVX2 and narrower: the rows of a band two pixels at
    a time, the spheres GROUP at a time. The cull test of a whole group on
    both rays is one SIMD loop across the spheres (each sphere's EO loaded
    once for two rays), and only a group it cannot rule out is walked again,
    sphere by sphere, with the exact test. Same arithmetic, same order of
    spheres, same pixels as _render_band."""
    ex, ey, ez, es = relative[0], relative[1], relative[2], relative[3]
    ox, oy, oz = basis[0, 0], basis[0, 1], basis[0, 2]
    for y in range(first_row, end_row):
        if stop[0]:
            return
        for x in range(0, width, 2):
            x1 = min(x + 1, width - 1)  # an odd width traces its last pixel twice, stores it once
            ax, ay, az = _primary_ray(x, y, width, height, basis)
            bx, by, bz = _primary_ray(x1, y, width, height, basis)
            a_closest, a_hit, a_d = FAR, -1, ZERO
            b_closest, b_hit, b_d = FAR, -1, ZERO
            for first in range(0, count, GROUP):
                end = min(first + GROUP, count)
                maybe = False
                for i in range(_U(first), _U(end)):
                    maybe |= _may_hit(ex[i], ey[i], ez[i], es[i], ax, ay, az) | _may_hit(
                        ex[i], ey[i], ez[i], es[i], bx, by, bz
                    )
                if maybe:
                    for i in range(first, end):
                        if _may_hit(ex[i], ey[i], ez[i], es[i], ax, ay, az):
                            t, d = _hit_from(_seen_from(_read(spheres, i), ox, oy, oz), ax, ay, az)
                            if t < a_closest and t > ZERO:
                                a_closest, a_hit, a_d = t, i, d
                        if _may_hit(ex[i], ey[i], ez[i], es[i], bx, by, bz):
                            t, d = _hit_from(_seen_from(_read(spheres, i), ox, oy, oz), bx, by, bz)
                            if t < b_closest and t > ZERO:
                                b_closest, b_hit, b_d = t, i, d
            _store_pixel(x, y, a_hit, a_d, spheres, image, hits)
            if x1 > x:
                _store_pixel(x1, y, b_hit, b_d, spheres, image, hits)


@compiled.njit(nogil=True)
def _wide_band(first_row, end_row, width, height, basis, spheres, relative, count, image, hits, stop):
    """The fast kernel for AVX-512: WIDE pixels of a row side by side, so the
    cull test of each sphere is one SIMD compare across the rays; a group of
    GROUP spheres is walked again with the exact test only where some ray
    may hit one of them. Same arithmetic, same order, same pixels."""
    ex, ey, ez, es = relative[0], relative[1], relative[2], relative[3]
    ox, oy, oz = basis[0, 0], basis[0, 1], basis[0, 2]
    dx = np.empty(WIDE, np.float32)
    dy = np.empty(WIDE, np.float32)
    dz = np.empty(WIDE, np.float32)
    closest = np.empty(WIDE, np.float32)
    hit = np.empty(WIDE, np.int64)
    hit_d = np.empty(WIDE, np.float32)
    for y in range(first_row, end_row):
        if stop[0]:
            return
        for x in range(0, width, WIDE):
            for k in range(WIDE):  # pixels past the edge trace a copy of the last one, unstored
                dx[k], dy[k], dz[k] = _primary_ray(min(x + k, width - 1), y, width, height, basis)
                closest[k], hit[k], hit_d[k] = FAR, -1, ZERO
            for first in range(0, count, GROUP):
                end = min(first + GROUP, count)
                maybe = False
                for i in range(_U(first), _U(end)):
                    for k in range(WIDE):
                        maybe |= _may_hit(ex[i], ey[i], ez[i], es[i], dx[k], dy[k], dz[k])
                if maybe:
                    for i in range(first, end):
                        # Most spheres of a group that passed are still missed by
                        # all 16 rays: one SIMD test across the rays first keeps
                        # the scalar loop for the spheres some ray may hit
                        # (step 5 of docs/notes/floors.md#each-version-against-the-floor).
                        some = False
                        for k in range(WIDE):
                            some |= _may_hit(ex[i], ey[i], ez[i], es[i], dx[k], dy[k], dz[k])
                        if not some:
                            continue
                        seen = _seen_from(_read(spheres, i), ox, oy, oz)
                        for k in range(WIDE):
                            if _may_hit(ex[i], ey[i], ez[i], es[i], dx[k], dy[k], dz[k]):
                                t, d = _hit_from(seen, dx[k], dy[k], dz[k])
                                if t < closest[k] and t > ZERO:
                                    closest[k], hit[k], hit_d[k] = t, i, d
            for k in range(min(WIDE, width - x)):
                _store_pixel(x + k, y, hit[k], hit_d[k], spheres, image, hits)


def _has_avx512() -> bool:
    """Whether the CPU Numba compiles for has 16-lane float32 registers."""
    try:
        from llvmlite import binding

        return bool(binding.get_host_cpu_features().get("avx512f", False))
    except Exception:  # noqa: BLE001 - an llvmlite without the query: the kernel that suits every CPU
        return False


# Which loop vectorises best depends on the register width: with AVX-512 the
# wide kernel (16 rays side by side) took half the pairs kernel's time, with
# AVX2 the pairs kernel was the faster (step 4 of
# docs/notes/floors.md#each-version-against-the-floor).
_fast_band = _wide_band if _has_avx512() else _pairs_band
