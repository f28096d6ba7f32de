"""Shading: the thesis's colour rule, and colour to bytes."""

import numpy as np

from .constants import HALF, ONE, ZERO

BYTE = np.float32(255.0)
MISS_XY = np.float32(1024.0)
MISS_Z = np.float32(786.0)


def make(jit):
    @jit
    def shade_hit(red, green, blue, r, d):
        """The thesis's colour: the sphere's colour darkened towards its rim,
        colour - (r - d) / r on every channel."""
        fade = (r - d) / r
        return red - fade, green - fade, blue - fade

    @jit
    def shade_miss(fx, fy):
        """The thesis's background gradient, (x / 1024, y / 1024, x / 786)."""
        return fx / MISS_XY, fy / MISS_XY, fx / MISS_Z

    @jit
    def to_byte(c):
        """floor(clamp(c, 0, 1) * 255 + 0.5), the design's colour-to-byte rule."""
        c = min(max(c, ZERO), ONE)
        # at least 0.5, so truncating is flooring: a conversion LLVM can
        # make SIMD (the CPU's packets shade their rays together)
        return np.uint8(np.int32(c * BYTE + HALF))

    return shade_hit, shade_miss, to_byte
