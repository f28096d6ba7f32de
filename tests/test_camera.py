"""The camera's basis against NumPy's own vector functions, bit for bit, on
fresh random cameras of every scale: raybench.camera writes the cross
product and the norm out, for speed, and must not change a single bit of
any frame's rays."""

import math

import numpy as np
import pytest

from raybench import Camera, RaybenchError


def numpy_basis(camera: Camera, width: int, height: int) -> np.ndarray:
    """The convention of raybench.camera's docstring in np.cross and np.linalg.norm."""
    pos = np.array(camera.position, dtype=np.float64)
    forward = np.array(camera.look_at, dtype=np.float64) - pos
    forward /= np.linalg.norm(forward)
    right = np.cross(forward, np.array(camera.up, dtype=np.float64))
    right /= np.linalg.norm(right)
    true_up = np.cross(right, forward)
    plane_h = 2.0 * math.tan(math.radians(camera.fov_deg) / 2.0)
    plane_w = plane_h * width / height
    return np.array([pos, forward, right * plane_w, true_up * plane_h], dtype=np.float32)


def random_camera(rng) -> Camera:
    scale = 10.0 ** rng.integers(-6, 14)
    position = rng.normal(size=3) * scale
    look_at = position + rng.normal(size=3) * scale * 10.0 ** rng.integers(-3, 3)
    up = rng.normal(size=3) * 10.0 ** rng.integers(-5, 5) if rng.random() < 0.7 else (0.0, 1.0, 0.0)
    return Camera(tuple(position), tuple(look_at), tuple(up), float(rng.uniform(1.0, 179.0)))


def test_the_basis_is_numpys_bit_for_bit(rng):
    compared = 0
    for _ in range(3000):
        try:
            camera = random_camera(rng)
        except RaybenchError:  # up parallel to the view, or a point beyond MAX_MAGNITUDE: refused, nothing to compare
            continue
        width, height = (int(v) for v in rng.integers(1, 4000, 2))
        got = camera.basis(width, height)
        assert got.dtype == np.float32 and got.shape == (4, 3)
        np.testing.assert_array_equal(got.view(np.int32), numpy_basis(camera, width, height).view(np.int32))
        compared += 1
    assert compared > 2500


def test_the_basis_is_orthogonal_and_scaled_to_the_view_plane(rng):
    for _ in range(200):
        camera = Camera(
            tuple(rng.uniform(-5, 5, 3)), tuple(rng.uniform(-5, 5, 3) + 20), tuple(rng.normal(size=3)), 60.0
        )
        _, forward, right, up = camera.basis(1680, 1050).astype(np.float64)
        plane_h = 2 * math.tan(math.radians(30))
        assert np.linalg.norm(forward) == pytest.approx(1, abs=1e-6)
        assert np.linalg.norm(right) == pytest.approx(plane_h * 1.6, rel=1e-6)
        assert np.linalg.norm(up) == pytest.approx(plane_h, rel=1e-6)
        for a, b in ((forward, right), (forward, up), (right, up)):
            assert abs(a @ b) < 1e-5
        assert np.dot(np.cross(right, forward), up) > 0  # true_up = cross(right, forward): row 0 is the top


def test_up_parallel_to_the_view_is_refused():
    with pytest.raises(RaybenchError, match="parallel"):
        Camera((1, 2, 3), (1, 2, 9), (0, 0, -2))
    with pytest.raises(RaybenchError, match="must differ"):
        Camera((1, 2, 3), (1, 2, 3))
