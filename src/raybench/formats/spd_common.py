"""What every SPD generator shares (raybench.formats.spd and the modules of
its larger scenes, spd_mount and spd_teapot): the sky, the fills'
highlight, and rotations."""

from __future__ import annotations

import math

import numpy as np

from .nff import Fill

# The SPD's "UNC sky blue", the background of every one of its scenes.
SKY = (0.078, 0.361, 0.753)


def phong_power(angle_deg: float) -> float:
    """The SPD's fills give a highlight's half-width angle; NFF's Shine is the
    Phong power whose cosine lobe falls to a half at that angle (lib's
    conversion: 0 degrees is a very sharp 100000, 90 or more a flat 1)."""
    a = math.radians(angle_deg)
    if a <= 0.0:
        return 100000.0
    if a >= math.pi / 2:
        return 1.0
    return math.log(0.5) / math.log(math.cos(a))


def _fill(colour, kd, ks, angle_deg, kt, ior) -> Fill:
    return Fill(tuple(colour), kd, ks, phong_power(angle_deg), kt, ior)


def _rotation(axis, angle) -> np.ndarray:
    """Rotation matrices by angle about unit axis (Rodrigues), for column
    vectors: axis (n, 3), angle (n,) give (n, 3, 3)."""
    axis = np.asarray(axis, np.float64).reshape(-1, 3)
    angle = np.asarray(angle, np.float64).reshape(-1)
    x, y, z = axis.T
    c, s = np.cos(angle), np.sin(angle)
    t = 1.0 - c
    return np.stack(
        [
            np.stack([t * x * x + c, t * x * y - s * z, t * x * z + s * y], -1),
            np.stack([t * x * y + s * z, t * y * y + c, t * y * z - s * x], -1),
            np.stack([t * x * z - s * y, t * y * z + s * x, t * z * z + c], -1),
        ],
        -2,
    )
