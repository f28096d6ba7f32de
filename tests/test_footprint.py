"""kernels/footprint.py: the rows and columns of a packet of primary rays
that a box can meet. Held to the rays the packets really cast
(packets._primary_ray_v, in float32) and a float64 slab test of each against
the box: every ray that meets it lies in the rows and columns given,
whatever the camera, and a box no ray meets is mostly ruled out whole."""

import numba
import numpy as np
import pytest

from raybench import Camera
from raybench.kernels import footprint, packets
from raybench.kernels.primitives import triangle

W, H = 16, 8  # a packet's pixels, the sphere's and the triangle's shape


def meets(direction, lo, hi) -> bool:
    """Whether the ray from the origin along direction (its float32 values,
    taken as exact) meets the box [lo, hi] (relative to the origin) at t >
    0: the slab test in float64, with 1/0 as infinity."""
    d = direction.astype(np.float64)
    with np.errstate(divide="ignore", invalid="ignore"):
        inv = 1.0 / d
        t1, t2 = lo * inv, hi * inv
    t1 = np.where(np.isnan(t1), -np.inf, t1)  # 0 * inf: a ray along the slab's plane
    t2 = np.where(np.isnan(t2), np.inf, t2)
    near = np.max(np.minimum(t1, t2))
    far = np.min(np.maximum(t1, t2))
    return bool(near <= far and far > 0)


def a_case(rng):
    """A camera, a frame size, a packet in it and a box near one of its
    rays (or anywhere), with the margin the walks would grow it by."""
    fov = float(rng.choice([rng.uniform(0.5, 5.0), rng.uniform(20, 100), rng.uniform(140, 170)]))
    scale = float(10.0 ** rng.uniform(-2, 4))
    position = rng.normal(size=3) * scale
    look_at = position + rng.normal(size=3)
    camera = Camera(tuple(position), tuple(look_at), fov_deg=fov)
    width, height = int(rng.integers(W, 3000)), int(rng.integers(H, 2000))
    basis = camera.basis(width, height)
    x0 = int(rng.integers(0, (width - 1) // W + 1)) * W
    y0 = int(rng.integers(0, (height - 1) // H + 1)) * H
    end_row = min(height, y0 + H * int(rng.integers(1, 3)))
    origin = basis[0].astype(np.float64)
    x, y = x0 + int(rng.integers(W)), y0 + int(rng.integers(H))
    d = np.array(packets._primary_ray_v(np.int32(min(x, width - 1)), np.int32(min(y, end_row - 1)), width, height,
                                        basis), np.float64)  # fmt: skip
    centre = origin + d * scale * 10.0 ** rng.uniform(-3, 2) if rng.random() < 0.9 else origin + rng.normal(size=3)
    if rng.random() < 0.1:
        centre = origin - d * scale  # behind the camera
    size = scale * 10.0 ** rng.uniform(-6, 0.5) * rng.uniform(0.1, 1.0, 3)
    lo = (centre - size).astype(np.float32)
    hi = (centre + size).astype(np.float32)
    ox, oy, oz = (np.float32(v) for v in basis[0])
    margin = (abs(ox) + abs(oy) + abs(oz)) * np.float32(2.0**-16)
    return basis, width, height, x0, y0, end_row, lo, hi, margin


def packet_rays(basis, width, height, x0, y0, end_row):
    """The packet's rays that the frame stores, as the packets cast them
    (packets._primary_ray_v, float32): (k, its direction) for each, rays
    past the frame's edge (copies of its last pixels, unstored) left out."""
    for k in range(W * H):
        x, y = min(x0 + k % W, width - 1), min(y0 + k // W, end_row - 1)
        if x != x0 + k % W or y != y0 + k // W:
            continue  # a copy of the frame's last pixel, unstored
        yield k, packets._primary_ray_v(np.int32(x), np.int32(y), width, height, basis)


def place_of(width, x0, y0, end_row):
    """The packet at (x0, y0)'s place: its first and last pixels' columns and rows."""
    return (x0, y0, min(x0 + W, width) - 1, min(y0 + H, end_row) - 1)


def assert_a_window(first, end, first_column, end_column):
    """Rows and columns within the packet; columns given wherever rows are."""
    assert 0 <= first <= end <= H
    assert first == end or 0 <= first_column < end_column <= W


@pytest.mark.parametrize("batch", range(4))
def test_every_ray_that_meets_the_box_is_in_its_window(rng, batch):
    ruled_out = met = 0
    for _ in range(500):
        basis, width, height, x0, y0, end_row, lo, hi, margin = a_case(rng)
        view = footprint.frame_view(basis, width, height)
        place = place_of(width, x0, y0, end_row)
        ox, oy, oz = (np.float32(v) for v in basis[0])
        box = tuple(np.float32(v) for v in (*lo, *hi))
        first, end, first_column, end_column = footprint.window_of(view, place, H, W, box, margin, ox, oy, oz)
        assert_a_window(first, end, first_column, end_column)
        origin = basis[0].astype(np.float64)
        grown_lo = lo.astype(np.float64) - np.float64(margin) - origin
        grown_hi = hi.astype(np.float64) + np.float64(margin) - origin
        any_met = False
        for k, d in packet_rays(basis, width, height, x0, y0, end_row):
            if meets(np.array(d), grown_lo, grown_hi):
                any_met = True
                assert first <= k // W < end and first_column <= k % W < end_column, (
                    k,
                    first,
                    end,
                    first_column,
                    end_column,
                    basis,
                    width,
                    height,
                    x0,
                    y0,
                    lo,
                    hi,
                )
        met += any_met
        ruled_out += (not any_met) and first == end
    assert met > 100  # most boxes lie across a ray of the packet: the rows were tested
    assert ruled_out > 0  # and some that none meets were ruled out whole


def test_a_box_beside_the_packet_or_before_one_pixel_is_cut_to_it():
    """A straight-on camera, 160x80: a small box in front of another
    packet's pixels meets none of this packet's rays; one in front of pixel
    (5, 3) of the packet at (16, 8) meets its row 3 and column 5 alone."""
    width, height = 160, 80
    basis = Camera((0.0, 0.0, 0.0), (0.0, 0.0, 1.0), fov_deg=60.0).basis(width, height)
    view = footprint.frame_view(basis, width, height)
    zero = np.float32(0.0)

    def box_at(x, y, half):
        d = np.array(packets._primary_ray_v(np.int32(x), np.int32(y), width, height, basis), np.float64) * 5.0
        return tuple(np.float32(v) for v in (*(d - half), *(d + half)))

    tiny = 1e-4  # far less than a pixel (5 units away, a pixel is about 0.036 across)
    place = (16, 8, 31, 15)
    assert footprint.window_of(view, place, H, W, box_at(60, 40, tiny), zero, zero, zero, zero)[:2] == (0, 0)
    assert footprint.window_of(view, place, H, W, box_at(21, 11, tiny), zero, zero, zero, zero) == (3, 4, 5, 6)


def test_a_singular_view_culls_nothing():
    basis = np.zeros((4, 3), np.float32)
    view = footprint.frame_view(basis, 64, 32)
    assert view == footprint.OFF
    box = (np.float32(1.0),) * 3 + (np.float32(2.0),) * 3
    assert footprint.window_of(view, (0, 0, 15, 7), H, W, box, np.float32(0.0), *(np.float32(0.0),) * 3) == (0, H, 0, W)


TRIANGLE = triangle.make(numba.njit)


def a_triangle(rng, basis, width, height, x0, y0, end_row, lo, hi):
    """A triangle for a_case's packet: inside the case's box, or with its
    vertices on or beside the packet's own rays (an edge through a pixel's
    centre, where the test's rounding decides), or reaching behind the
    camera."""
    origin = basis[0].astype(np.float64)
    choice = rng.random()
    if choice < 0.4:
        return rng.uniform(lo, hi, (3, 3)).astype(np.float32)
    vertices = np.empty((3, 3))
    for i in range(3):
        x, y = x0 + int(rng.integers(-1, W + 1)), y0 + int(rng.integers(-1, H + 1))
        x, y = min(max(x, 0), width - 1), min(max(y, 0), end_row - 1)
        d = np.array(packets._primary_ray_v(np.int32(x), np.int32(y), width, height, basis), np.float64)
        distance = np.linalg.norm(hi.astype(np.float64) - lo) * rng.uniform(0.5, 2.0) + 1e-3
        vertices[i] = origin + d * distance * (1.0 if choice < 0.9 or i else -0.3)
    return vertices.astype(np.float32)


@pytest.mark.parametrize("batch", range(4))
def test_every_ray_that_hits_a_triangle_is_in_its_window(rng, batch):
    """The triangle's window (its vertices' footprint, tighter than its
    box's) holds every ray of the packet that the triangle's own test hits,
    edges through pixels' centres among them."""
    hits = ruled_out = 0
    for _ in range(400):
        basis, width, height, x0, y0, end_row, lo, hi, margin = a_case(rng)
        view = footprint.frame_view(basis, width, height)
        place = place_of(width, x0, y0, end_row)
        ox, oy, oz = (np.float32(v) for v in basis[0])
        vertices = a_triangle(rng, basis, width, height, x0, y0, end_row, lo, hi)
        row = tuple(np.float32(v) for v in vertices.ravel())
        first, end, first_column, end_column = TRIANGLE.window(view, place, H, W, row, margin, ox, oy, oz)
        assert_a_window(first, end, first_column, end_column)
        any_hit = False
        for k, (dx, dy, dz) in packet_rays(basis, width, height, x0, y0, end_row):
            t, _ = TRIANGLE.intersect(ox, oy, oz, dx, dy, dz, *row)
            if t > 0:
                any_hit = True
                assert first <= k // W < end and first_column <= k % W < end_column, (k, row, basis, width, height)
        hits += any_hit
        ruled_out += (not any_hit) and first == end
    assert hits > 100
    assert ruled_out > 0
