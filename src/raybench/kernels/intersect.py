"""Ray against sphere: the thesis's rayVsSphere (Appendix A), and the cheap
test that lets the fast kernels skip most spheres without changing a pixel."""

import math

import numpy as np

from .constants import ZERO

# The cull test's slack, relative to |EO|^2 + r^2: 64 float32 epsilons, several
# times the rounding of either discriminant (derivation in prepare_sphere).
CULL_SLACK = np.float32(64.0 * 2.0**-24)
# The cull threshold's slack, relative to |EO|: 64 float32 epsilons, covering
# a v computed with fused multiply-adds in one place and without in another.
ALONG_SLACK = np.float32(64.0 * 2.0**-24)


def build(jit):
    @jit
    def along(ex, ey, ez, dx, dy, dz):
        """v = EO.dir, how far along the ray the sphere's centre lies: the
        first line of intersect_relative, and all of the cull test."""
        return ex * dx + ey * dy + ez * dz

    @jit
    def chord(ex, ey, ez, r, dx, dy, dz):
        """v = EO.dir and the discriminant r^2 - |EO - v dir|^2: the ray meets
        the sphere where disc >= 0, at v -+ sqrt(disc)."""
        v = along(ex, ey, ez, dx, dy, dz)
        px = ex - v * dx
        py = ey - v * dy
        pz = ez - v * dz
        return v, r * r - (px * px + py * py + pz * pz)

    @jit
    def intersect_relative(ex, ey, ez, r, dx, dy, dz):
        """Distance t along the unit ray to the sphere's near surface and the
        half-chord d (the thesis's `d`, which its shading uses); t = -1 on a miss.
        (ex, ey, ez) is EO, the sphere's centre minus the ray's origin.
        disc = r^2 - |EO - v dir|^2 equals the thesis's r^2 - (EO.EO - v^2) but
        keeps its digits in float32: the thesis's form subtracts two squares of
        the sphere's distance and loses everything for small, far spheres.
        """
        v, disc = chord(ex, ey, ez, r, dx, dy, dz)
        if disc < ZERO:
            return np.float32(-1.0), ZERO
        d = np.float32(math.sqrt(disc))
        return v - d, d

    @jit
    def intersect_ahead(ex, ey, ez, r, dx, dy, dz, far_only):
        """The secondary rays' test: the first crossing of the sphere ahead of
        the origin, the near root from outside and the far root from inside
        (a ray in a glass sphere, a camera in one); far_only takes the far
        root whatever the near one, for a ray that starts on this very sphere
        and goes into it. Same (t, d) as intersect_relative where the near
        root is ahead; t <= 0 where nothing is."""
        v, disc = chord(ex, ey, ez, r, dx, dy, dz)
        if disc < ZERO:
            return np.float32(-1.0), ZERO
        d = np.float32(math.sqrt(disc))
        t = v - d
        if far_only or t <= ZERO:
            t = v + d
        return t, d

    @jit
    def intersect_sphere(ox, oy, oz, dx, dy, dz, cx, cy, cz, r):
        """intersect_relative for a ray from (ox, oy, oz)."""
        return intersect_relative(cx - ox, cy - oy, cz - oz, r, dx, dy, dz)

    @jit
    def prepare_sphere(ox, oy, oz, cx, cy, cz, r):
        """Per frame and sphere: EO (exactly as intersect_sphere computes it) and
        the cull threshold s of may_hit: a ray can only hit where v > s.

        Why it holds. intersect_relative accepts only t = v - d > 0 with
        d >= 0, so v > 0. For a unit ray, |EO - v dir|^2 = |EO|^2 - v^2, so
        disc >= 0 needs v^2 >= q = |EO|^2 - r^2 (the thesis's cheap form).
        Hence a hit needs v > sqrt(q) (v > 0 where q <= 0). In float32 the
        rounding of either discriminant, and a ray of length 1 only to a few
        epsilons, move q by a few epsilons of |EO|^2 + r^2: lowered by
        CULL_SLACK (|EO|^2 + r^2), q is below every v^2 the exact test can
        accept by a margin that also covers the rounding of the square root.
        v itself may be computed with or without fused multiply-adds (a
        compiler's choice), which moves it by a few epsilons of |EO|: s is
        lowered by ALONG_SLACK |EO|. So the test only ever skips certain
        misses, and the fast kernels give the same pixels as the simple ones.
        """
        ex = cx - ox
        ey = cy - oy
        ez = cz - oz
        e2 = ex * ex + ey * ey + ez * ez
        r2 = r * r
        q = (e2 - r2) - CULL_SLACK * (e2 + r2)
        s = np.float32(math.sqrt(q)) if q > ZERO else ZERO
        return ex, ey, ez, s - ALONG_SLACK * np.float32(math.sqrt(e2))

    @jit
    def may_hit(ex, ey, ez, s, dx, dy, dz):
        """False only where the ray certainly misses the sphere (see
        prepare_sphere): one dot product and a compare."""
        return along(ex, ey, ez, dx, dy, dz) > s

    return intersect_relative, intersect_sphere, prepare_sphere, may_hit, along, intersect_ahead
