"""Ray against sphere: the thesis's rayVsSphere (Appendix A), and the cheap
test that lets the fast kernels skip most spheres without changing a pixel."""

import math

import numpy as np

ZERO = np.float32(0.0)
# The cull test's slack, relative to |EO|^2 + r^2: 64 float32 epsilons, several
# times the rounding of either discriminant (derivation in prepare_sphere).
CULL_SLACK = np.float32(64.0 * 2.0 ** -24)


def build(jit):
    @jit
    def intersect_relative(ex, ey, ez, r, dx, dy, dz):
        """Distance t along the unit ray to the sphere's near surface and the
        half-chord d (the thesis's `d`, which its shading uses); t = -1 on a miss.
        (ex, ey, ez) is EO, the sphere's centre minus the ray's origin.
        disc = r^2 - |EO - v dir|^2 equals the thesis's r^2 - (EO.EO - v^2) but
        keeps its digits in float32: the thesis's form subtracts two squares of
        the sphere's distance and loses everything for small, far spheres.
        """
        v = ex * dx + ey * dy + ez * dz
        px = ex - v * dx
        py = ey - v * dy
        pz = ez - v * dz
        disc = r * r - (px * px + py * py + pz * pz)
        if disc < ZERO:
            return np.float32(-1.0), ZERO
        d = np.float32(math.sqrt(disc))
        return v - d, d

    @jit
    def intersect_sphere(ox, oy, oz, dx, dy, dz, cx, cy, cz, r):
        """intersect_relative for a ray from (ox, oy, oz)."""
        return intersect_relative(cx - ox, cy - oy, cz - oz, r, dx, dy, dz)

    @jit
    def prepare_sphere(ox, oy, oz, cx, cy, cz, r):
        """Per frame and sphere: EO (exactly as intersect_sphere computes it) and
        the cull bound q of may_hit.

        For a unit ray, |EO - v dir|^2 = |EO|^2 - v^2, so the ray can only hit
        where v^2 > |EO|^2 - r^2: the thesis's cheap form, three multiply-adds
        for v and one more. In float32 its rounding is a few epsilons of
        |EO|^2 (and the ray's length is 1 only to a few epsilons), so it
        cannot decide a hit, but with q lowered by CULL_SLACK (|EO|^2 + r^2)
        it never rejects a sphere that intersect_relative would accept: the
        fast kernels skip only certain misses and give the same pixels.
        """
        ex = cx - ox
        ey = cy - oy
        ez = cz - oz
        e2 = ex * ex + ey * ey + ez * ez
        r2 = r * r
        return ex, ey, ez, (e2 - r2) - CULL_SLACK * (e2 + r2)

    @jit
    def may_hit(ex, ey, ez, q, dx, dy, dz):
        """False only where the ray certainly misses the sphere (see prepare_sphere)."""
        v = ex * dx + ey * dy + ez * dz
        return v * v > q

    return intersect_relative, intersect_sphere, prepare_sphere, may_hit
