"""Spheres that move: a scene animated by a seed and a time, the same on every
machine.

Each sphere orbits on a circle through its starting centre, in a plane of
its own (random orientation), AMPLITUDE times its own size (scene.sizes)
from the circle's centre, at an angular speed of one turn in PERIOD_S[0] to
PERIOD_S[1] seconds. At time 0 the spheres are the scene's own; only their
centres move. The motion is small against the scene (each sphere stays
within 2 * AMPLITUDE of its sizes of its start), so a tree refitted to it
degrades slowly, as the spheres of a real dynamic scene move between frames.
"""

from __future__ import annotations

import numpy as np

from .errors import RaybenchError, shown
from .layout import CX, CZ
from .scene import sizes

AMPLITUDE = 1.5
PERIOD_S = (2.0, 8.0)


class Orbits:
    """The animation of a (7, N) float32 sphere array by seed: at(t) gives the
    spheres at time t seconds."""

    def __init__(self, spheres: np.ndarray, seed: int = 0):
        if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or seed < 0:
            raise RaybenchError(f"seed: must be a non-negative integer, got {shown(seed)}")
        self.spheres = spheres
        n = spheres.shape[1]
        rng = np.random.default_rng([int(seed), 0x0A11])  # apart from random_spheres' stream of the same seed
        # the circle's plane: u, v orthonormal, from a random direction
        axis = rng.normal(size=(n, 3))
        axis /= np.maximum(np.linalg.norm(axis, axis=1, keepdims=True), 1e-12)
        helper = np.where(np.abs(axis[:, :1]) < 0.9, [[1.0, 0.0, 0.0]], [[0.0, 1.0, 0.0]])
        u = np.cross(axis, helper)
        u /= np.linalg.norm(u, axis=1, keepdims=True)
        self.u, self.v = u, np.cross(axis, u)
        self.omega = 2 * np.pi / rng.uniform(*PERIOD_S, n)
        self.phase = rng.uniform(0, 2 * np.pi, n)
        self.amplitude = AMPLITUDE * sizes(spheres)
        self.start = spheres[CX : CZ + 1].astype(np.float64)

    def at(self, t: float) -> np.ndarray:
        """The spheres at time t (seconds): a new (7, N) float32 array."""
        if not np.isfinite(t):
            raise RaybenchError(f"time: must be a finite number of seconds, got {shown(t)}")
        angle = self.omega * t + self.phase
        cos = (np.cos(angle) - np.cos(self.phase)) * self.amplitude
        sin = (np.sin(angle) - np.sin(self.phase)) * self.amplitude
        out = self.spheres.copy()
        out[CX : CZ + 1] = (self.start + (self.u * cos[:, None] + self.v * sin[:, None]).T).astype(np.float32)
        return out
