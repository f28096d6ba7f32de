"""Ray against sphere: the thesis's rayVsSphere (Appendix A)."""

import math

import numpy as np

ZERO = np.float32(0.0)


def build(jit):
    @jit
    def intersect_sphere(ox, oy, oz, dx, dy, dz, cx, cy, cz, r):
        """Distance t along the unit ray to the sphere's near surface and the
        half-chord d (the thesis's `d`, which its shading uses); t = -1 on a miss.

        disc = r^2 - |EO - v dir|^2 equals the thesis's r^2 - (EO.EO - v^2) but
        keeps its digits in float32: the thesis's form subtracts two squares of
        the sphere's distance and loses everything for small, far spheres.
        """
        ex = cx - ox
        ey = cy - oy
        ez = cz - oz
        v = ex * dx + ey * dy + ez * dz
        px = ex - v * dx
        py = ey - v * dy
        pz = ez - v * dz
        disc = r * r - (px * px + py * py + pz * pz)
        if disc < ZERO:
            return np.float32(-1.0), ZERO
        d = np.float32(math.sqrt(disc))
        return v - d, d

    return intersect_sphere
