"""The pinhole camera and the per-frame basis every backend's kernel reads.

Convention (every backend's, and tests/reference.py's): forward = normalize(look_at - position),
right = normalize(cross(forward, up)), true_up = cross(right, forward); the view
plane sits at distance 1 along forward, plane_h = 2 tan(fov/2) high and
plane_w = plane_h * W / H wide. Row 0 of the image is the top.
"""

from __future__ import annotations

import math
import numbers
from dataclasses import dataclass

import numpy as np

from .errors import RaybenchError, shown

# Coordinates and radii are squared in float32 inside the kernels; beyond this
# magnitude the squares overflow or swamp every other term.
MAX_MAGNITUDE = 1e15


def _real(value) -> bool:
    """A real number (NumPy's included), not a bool, a string or a complex."""
    return isinstance(value, numbers.Real) and not isinstance(value, (bool, np.bool_))


def _vector(value, name: str) -> tuple[float, float, float]:
    try:
        # Real numbers only: a string would be read digit by digit, and a
        # complex number would lose its imaginary part.
        if isinstance(value, (str, bytes)) or not all(_real(c) for c in value):
            raise TypeError
        vec = tuple(float(c) for c in value)
    except (TypeError, ValueError, OverflowError):
        raise RaybenchError(f"{name}: must be 3 numbers [x, y, z], got {shown(value)}") from None
    if len(vec) != 3 or not all(math.isfinite(c) and abs(c) <= MAX_MAGNITUDE for c in vec):
        raise RaybenchError(
            f"{name}: must be 3 finite numbers [x, y, z], each at most {MAX_MAGNITUDE:g} in magnitude, "
            f"got {shown(value)}"
        )
    return vec


# A basis is made every frame, and on three numbers NumPy's calls cost far more
# than their arithmetic (docs/notes/startup.md#what-a-renderer-costs-over-its-tracer-2-vcpu-machine,
# "The basis without NumPy's calls"). So these two are that arithmetic alone:
# np.linalg.norm of a vector
# is the square root of its dot with itself, and np.cross multiplies, then
# subtracts, as Python's floats do here. The basis stays bit for bit NumPy's
# (tests/test_camera.py).


def _norm(v: np.ndarray) -> float:
    return math.sqrt(v.dot(v))


def _cross(a, b) -> np.ndarray:
    a0, a1, a2 = a
    b0, b1, b2 = b
    return np.array([a1 * b2 - a2 * b1, a2 * b0 - a0 * b2, a0 * b1 - a1 * b0])


@dataclass(frozen=True)
class Camera:
    position: tuple[float, float, float] = (0.0, 0.0, 0.0)
    look_at: tuple[float, float, float] = (0.0, 0.0, 1.0)
    up: tuple[float, float, float] = (0.0, 1.0, 0.0)
    fov_deg: float = 60.0

    def __post_init__(self):
        # Validate once, here, so every later stage may trust the camera.
        pos = _vector(self.position, "camera.position")
        look = _vector(self.look_at, "camera.look_at")
        up = _vector(self.up, "camera.up")
        object.__setattr__(self, "position", pos)
        object.__setattr__(self, "look_at", look)
        object.__setattr__(self, "up", up)
        try:
            if not _real(self.fov_deg):
                raise TypeError
            fov = float(self.fov_deg)
        except (TypeError, ValueError, OverflowError):
            raise RaybenchError(
                f"camera.fov_deg: must be a number of degrees in (0, 180), got {shown(self.fov_deg)}"
            ) from None
        if not (0.0 < fov < 180.0):
            raise RaybenchError(f"camera.fov_deg: must be in (0, 180) degrees, got {shown(self.fov_deg)}")
        object.__setattr__(self, "fov_deg", fov)
        forward = np.subtract(look, pos)
        length = _norm(forward)
        if not length > 0.0:
            raise RaybenchError("camera.look_at: must differ from camera.position")
        if not _norm(_cross(forward.tolist(), up)) > 1e-12 * length * max(_norm(np.array(up)), 1e-300):
            raise RaybenchError("camera.up: must not be zero or parallel to the view direction (look_at - position)")

    def basis(self, width: int, height: int) -> np.ndarray:
        """The (4, 3) float32 array [origin, forward, right * plane_w, true_up * plane_h]
        from which a kernel makes the ray of any pixel."""
        pos = np.array(self.position, dtype=np.float64)
        forward = np.array(self.look_at, dtype=np.float64) - pos
        forward /= _norm(forward)
        right = _cross(forward.tolist(), self.up)
        right /= _norm(right)
        true_up = _cross(right.tolist(), forward.tolist())
        plane_h = 2.0 * math.tan(math.radians(self.fov_deg) / 2.0)
        plane_w = plane_h * width / height
        return np.array([pos, forward, right * plane_w, true_up * plane_h], dtype=np.float32)

    def to_dict(self) -> dict:
        return {
            "position": list(self.position),
            "look_at": list(self.look_at),
            "up": list(self.up),
            "fov_deg": self.fov_deg,
        }
