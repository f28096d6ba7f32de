"""NFF's polygons and cones as triangles (raybench.formats.polygons), held to
the geometry they stand for: a concave polygon's triangles cover exactly its
area, each turned its way; a cone's corners lie on the cone, its normals are
the cone's, its triangles face outwards and none has no area; count() is
len(triangles()) on every SPD scene."""

import numpy as np
import pytest

from raybench.formats import nff, polygons, spd


def areas(corners: np.ndarray) -> np.ndarray:
    return np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0])


def test_a_concave_polygon_is_cut_into_its_own_area():
    # a star of 5 points in a tilted plane: concave at every inner corner
    k = np.arange(10)
    r = np.where(k % 2 == 0, 2.0, 0.7)
    flat = np.stack([r * np.cos(k * np.pi / 5), r * np.sin(k * np.pi / 5), np.zeros(10)], axis=1)
    turn = np.array([[1, 0, 0], [0, np.cos(0.6), -np.sin(0.6)], [0, np.sin(0.6), np.cos(0.6)]])
    star = flat @ turn.T + [3.0, -1.0, 2.0]
    tri = polygons.fans([nff.Polygon(star, None, 0)])
    normal = turn @ [0.0, 0.0, 1.0]
    assert len(tri) == 8
    area = areas(tri.corners) @ normal
    assert (area > 0).all()  # every triangle turned the polygon's way (counter-clockwise from its front)
    shoelace = 0.5 * abs(np.cross(flat, np.roll(flat, -1, axis=0))[:, 2].sum())
    assert 0.5 * area.sum() == pytest.approx(shoelace, rel=1e-12)
    # and a fan would not have been: its first triangles cross the notches
    fan = np.stack([np.repeat(star[:1], 8, 0), star[1:-1], star[2:]], axis=1)
    assert (areas(fan) @ normal < 0).any()


def test_a_convex_polygon_stays_a_fan():
    square = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]], float)
    tri = polygons.fans([nff.Polygon(square, None, 3)])
    assert tri.corners.tolist() == [[[0, 0, 0], [1, 0, 0], [1, 1, 0]], [[0, 0, 0], [1, 1, 0], [0, 1, 0]]]
    assert tri.fill.tolist() == [3, 3] and not tri.smooth.any()


@pytest.mark.parametrize(
    "row",
    [
        [0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 2.0, 1.0],  # a cylinder along z
        [1.0, 2.0, 3.0, 0.5, 4.0, -1.0, 7.0, 0.2],  # a slanted frustum
        [0.0, 0.0, 0.0, 1.0, 0.3, 0.2, 3.0, 0.0],  # a pointed cone
        [0.0, 0.0, 0.0, 0.0, 0.0, 5.0, 0.0, 0.4],  # pointed at its base
    ],
)
def test_a_cone_lies_on_the_cone_with_its_normals(row):
    row = np.array(row)
    tri = polygons.cones(row[None], np.array([0]))
    m = int(polygons.bands(row[None])[0])
    tips = (row[3] == 0) + (row[7] == 0)
    assert len(tri) == polygons.CONE_SEGMENTS * (2 * m - tips)
    base, apex = row[:3], row[4:7]
    axis = apex - base
    height = np.linalg.norm(axis)
    a = axis / height
    p = tri.corners.reshape(-1, 3)
    t = (p - base) @ a / height  # along the axis, 0 to 1
    radial = (p - base) - np.outer(t * height, a)
    assert (t > -1e-12).all() and (t < 1 + 1e-12).all()
    # on the surface: its distance from the axis is the radius there
    assert np.linalg.norm(radial, axis=1) == pytest.approx(row[3] + t * (row[7] - row[3]), abs=1e-12)
    n = tri.normals.reshape(-1, 3)
    assert np.linalg.norm(n, axis=1) == pytest.approx(1.0)
    # at right angles to the slant through the point, and outwards
    off_axis = np.linalg.norm(radial, axis=1) > 1e-9  # a tip has no radial direction of its own
    w = radial[off_axis] / np.linalg.norm(radial[off_axis], axis=1, keepdims=True)
    slant = axis + (row[7] - row[3]) * w
    assert np.abs(np.einsum("ij,ij->i", n[off_axis], slant)) == pytest.approx(0.0, abs=1e-9)
    assert (np.einsum("ij,ij->i", n[off_axis], w) > 0).all()
    # every triangle has area and faces out: its plane's normal along the corners' normals
    face = areas(tri.corners)
    assert (np.linalg.norm(face, axis=1) > 0).all()
    assert (np.einsum("ij,ij->i", face, tri.normals.mean(axis=1)) > 0).all()


def test_a_long_cylinder_is_cut_into_bands():
    row = np.array([[0.0, 0, 0, 0.1, 3.0, 0, 0, 0.1]])  # 30 radii long
    assert polygons.bands(row).tolist() == [15]
    tri = polygons.cones(row, np.array([0]))
    length = np.ptp(tri.corners[..., 0], axis=1)  # each triangle's extent along the axis
    assert length.max() == pytest.approx(0.2)  # one band: 2 radii


def test_a_circle_of_no_height_gives_no_triangles():
    row = np.array([[0.0, 0, 0, 1.0, 0, 0, 0, 1.0]])
    assert len(polygons.cones(row, np.array([0]))) == 0


@pytest.mark.parametrize("name", sorted(spd.SCENES))
def test_the_count_is_the_triangles_made(name):
    for size in (1, 2, 3):
        scene = spd.generate(name, size)
        made = polygons.triangles(scene)
        assert polygons.count(scene) == len(made)
        assert np.isfinite(made.corners).all() and np.isfinite(made.normals).all()
