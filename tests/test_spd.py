"""The SPD generators (raybench.formats.spd): primitive counts against the
figures in the SPD's own documentation, bounds, and spot values from the
output of Haines's C programs; and a sphereflake rendered on the CPU
against tests/reference.py's float64 model."""

import math

import numpy as np
import pytest
from reference import check_frame, trace
from test_cli import assert_user_error, cli
from test_mixed import both_reference

import raybench
from raybench.errors import RaybenchError
from raybench.formats import nff, spd

# balls.c's header ("Total spheres = sum of n=0,SF of (9**SF)": 10, 91, 820
# at 1 to 3, 7381 at 4) and the 66,430 at 5 and 597,871 at 6; one
# floor square at every size. The README's table gives balls 7382 primitives
# at the default size 4 (the spheres and the floor).
BALLS = {1: 10, 2: 91, 3: 820, 4: 7381, 5: 66430, 6: 597871}
# tetra.c's header ("Total triangular polygons = 4**SF": 4, 16, 64 at 1 to
# 3, 4096 at 6), the README's 4096 primitives at the default size 6.
TETRA = {1: 4, 2: 16, 3: 64, 4: 256, 5: 1024, 6: 4096}


@pytest.mark.parametrize("size", sorted(BALLS))
def test_balls_counts_and_bounds(size):
    scene = spd.generate("balls", size)
    assert scene.counts() == {"spheres": BALLS[size], "polygons": 1, "patches": 0, "cones": 0}
    s = scene.spheres
    # every sphere inside the unit sphere ("radius of sphere which would
    # enclose entire object"), none below the floor, which the first touches
    reach = np.linalg.norm(s[:, :3], axis=1) + s[:, 3]
    assert reach.max() <= 1.0 and reach.max() > 0.5 + (size > 1) * 0.3
    assert (s[:, 2] - s[:, 3]).min() == pytest.approx(-0.5)
    radii, counts = np.unique(s[:, 3], return_counts=True)
    assert np.allclose(sorted(radii, reverse=True), [0.5 / 3**k for k in range(size + 1)])
    assert sorted(counts.tolist()) == [9**k for k in range(size + 1)]


def test_balls_is_haines_balls():
    """The view, lights, fills and floor balls.c writes; and spheres as its
    output gives them (to its 6 significant digits), in its order."""
    scene = spd.balls(2)
    assert scene.view == nff.View((2.1, 1.3, 1.7), (0, 0, 0), (0, 0, 1), 45.0, 0.01, (512, 512))
    assert scene.background == (0.078, 0.361, 0.753)
    assert [p for p, _ in scene.lights] == [(4, 3, 2), (1, -4, 4), (-3, 1, 5)]
    floor, mirror = scene.fills
    assert floor == nff.Fill((1.0, 0.75, 0.33), 0.8, 0.0, 100000.0, 0.0, 1.0)
    assert (mirror.color, mirror.kd, mirror.ks, mirror.t, mirror.ior) == ((1.0, 0.9, 0.7), 0.5, 0.5, 0.0, 1.0)
    assert mirror.shine == pytest.approx(3.0827, abs=5e-5)  # a highlight half a degree wide at 37 degrees
    assert scene.polygons[0].vertices.tolist() == [[12, 12, -0.5], [-12, 12, -0.5], [-12, -12, -0.5], [12, -12, -0.5]]
    from_c = {0: (0, 0, 0, 0.5), 1: (0.272166, 0.272166, 0.544331, 0.166667),
              9: (0.239622, 0.082487, 0.655442, 0.0555556), 11: (0.643951, 0.172546, 0.0, 0.166667),
              90: (0.471405, -0.471405, -0.222222, 0.0555556)}  # fmt: skip
    for i, row in from_c.items():
        assert scene.spheres[i] == pytest.approx(row, abs=6e-7), i


@pytest.mark.parametrize("size", sorted(TETRA))
def test_tetra_counts_and_bounds(size):
    scene = spd.generate("tetra", size)
    assert scene.counts() == {"spheres": 0, "polygons": TETRA[size], "patches": 0, "cones": 0}
    corners = np.array([p.vertices for p in scene.polygons])
    assert corners.shape == (TETRA[size], 3, 3)
    assert np.abs(corners).max() == 1.0  # within the cube of its four outer corners
    # every face's normal (its first two edges) points out of its tetrahedron
    middle = corners.mean(axis=1)
    normal = np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 1])
    centre = corners.reshape(-1, 4 * 3, 3).mean(axis=1).repeat(4, axis=0)
    assert (np.einsum("ij,ij->i", normal, middle - centre) > 0).all()


def test_tetra_is_haines_tetra():
    scene = spd.tetra(3)
    assert scene.fills == [nff.Fill((1.0, 0.2, 0.2), 1.0, 0.0, 100000.0, 0.0, 0.0)]
    assert scene.lights == [((2.0, -18.0, -5.0), None)]
    assert scene.polygons[0].vertices.tolist() == [[-1, -1, 1], [-1, -0.5, 0.5], [-0.5, -1, 0.5]]
    assert scene.polygons[-1].vertices.tolist() == [[0.5, 1, 0.5], [0.5, 0.5, 1], [1, 1, 1]]


def test_a_generated_nff_reads_back():
    scene = spd.balls(3)
    back = nff.read(scene.text())
    assert back.counts() == scene.counts() and back.view == scene.view and set(back.fills) == set(scene.fills)
    assert np.allclose(back.spheres, scene.spheres, rtol=1e-8, atol=1e-9)


@pytest.mark.parametrize("name,size", [("balls", 0), ("balls", 8), ("tetra", 12), ("balls", 2.5), ("cube", 1)])
def test_a_size_or_name_out_of_range_is_refused(name, size):
    with pytest.raises(RaybenchError):
        spd.generate(name, size)


def test_the_phong_power_of_a_highlight_angle():
    assert spd.phong_power(0.0) == 100000.0 and spd.phong_power(90.0) == 1.0
    power = spd.phong_power(37.0)
    assert math.cos(math.radians(37.0)) ** power == pytest.approx(0.5)


def test_a_sphereflake_renders_as_the_float64_reference():
    """balls at size 2 (91 spheres) traced on the CPU, its own view at 40x30,
    agrees with the independent float64 model pixel for pixel; and with its
    floor, every pixel clear of an outline hits the float64 nearest of both
    kinds."""
    whole = spd.balls(2).scene()
    scene = whole.replaced(meshes=())
    frame = raybench.render(scene, scene.camera, 40, 30, device="cpu")
    ref = trace(scene, scene.camera, 40, 30)
    assert (ref.hits >= 0).mean() > 0.15 and len(np.unique(ref.hits)) > 20  # not a vacuous picture
    check_frame(frame, ref, context="balls size 2")
    frame = raybench.render(whole, whole.camera, 40, 30, device="cpu")
    index, _t, clear, _o, _d = both_reference(whole, 40, 30)
    assert clear.mean() > 0.9 and (index[clear] >= len(whole)).sum() > 100  # the floor is seen
    assert np.array_equal(frame.hits.ravel()[clear], index[clear])


def test_scene_spd_on_the_command_line(capsys, tmp_path):
    target = tmp_path / "balls.nff"
    code, out, err = cli(capsys, "scene", "spd", "balls", "--size", 3, "-o", target)
    assert code == 0, err
    assert out == f"wrote {target}: SPD balls at size factor 3: 820 spheres, 1 polygon\n"
    assert nff.load(target).counts()["spheres"] == 820
    code, out, err = cli(capsys, "scene", "spd", "balls", "--size", 9, "-o", target)
    assert_user_error(code, out, err, "--size", "from 1 to 7")
    code, out, err = cli(capsys, "scene", "spd", "tetra", "-o", tmp_path / "tetra.png")
    assert_user_error(code, out, err, "must be a .nff file")


# rings.c's header ("formula for # of spheres or cylinders = 5*SF*(SF+1)*(2*SF+1)":
# 30, 150, 420 at 1 to 3, 4200 at 7), the README's 8401 primitives at 7.
RINGS = {1: 30, 2: 150, 3: 420, 7: 4200}


@pytest.mark.parametrize("size", sorted(RINGS))
def test_rings_counts_and_bounds(size):
    scene = spd.generate("rings", size)
    assert scene.counts() == {"spheres": RINGS[size], "polygons": 1, "patches": 0, "cones": RINGS[size]}
    assert sum(scene.counts().values()) == RINGS[size] * 2 + 1
    # each object's 30 points lie on one sphere, of radius 1 / (1 + the tubes' radius)
    points = spd._dodecahedron_rings(spd.RING_RADIUS)
    assert np.linalg.norm(points, axis=1) * (1 + spd.RING_RADIUS) == pytest.approx(np.ones(30))
    edges = np.linalg.norm(points - np.roll(points.reshape(6, 5, 3), 1, axis=1).reshape(30, 3), axis=1)
    assert edges == pytest.approx(np.full(30, edges[0]))  # six regular pentagons of one size
    # a cylinder joins each sphere to the one before it on its ring
    assert np.array_equal(scene.cones[:, :4], scene.spheres)
    wall = scene.polygons[0].vertices
    assert (scene.spheres[:, 1] + spd.RING_RADIUS < wall[:, 1].min()).all()


def test_rings_is_haines_rings():
    scene = spd.rings(2)
    spread = 1 / math.sin(math.pi / 8)
    assert scene.view.position == (-1.0, -spread, 0.5) and scene.view.angle == 45.0
    assert scene.spheres[0] == pytest.approx((0.930995, 2.61313, 0, 0.07412), abs=6e-6)
    assert scene.cones[0, 4:] == pytest.approx((0.287693, 1.7277, 0, 0.07412), abs=6e-6)
    assert scene.polygons[0].vertices[0] == pytest.approx((3.37286, 7.83938, 4.87286), abs=6e-5)
    colours = [scene.fills[i].color for i in scene.sphere_fill[:30:5]]
    assert colours == [(1, 0, 0), (0, 1, 0), (0, 0, 1), (0, 1, 1), (1, 0, 1), (1, 1, 0)]


def test_the_command_line_names_every_generator():
    from raybench.cli.scene import SPD_NAMES

    assert SPD_NAMES == tuple(spd.SCENES)


# tree.c's header ("Total objects = 2**(SF+1)-1 cones and spheres + 1 square
# polygon": 3, 7, 15 at 1 to 3, 4095 at 11); the README's 8191 primitives at 11.
TREE = {1: 3, 2: 7, 3: 15, 11: 4095}


@pytest.mark.parametrize("size", sorted(TREE))
def test_tree_counts_and_bounds(size):
    scene = spd.generate("tree", size)
    assert scene.counts() == {"spheres": TREE[size], "polygons": 1, "patches": 0, "cones": TREE[size]}
    assert sum(scene.counts().values()) == 2 ** (size + 2) - 1
    # every branch grows from the tip of another (the trunk from the ground), tips carry the spheres
    tips = {tuple(np.round(c, 9)) for c in scene.cones[:, 4:7]}
    assert all(tuple(np.round(b, 9)) in tips for b in scene.cones[1:, :3])
    assert np.array_equal(scene.spheres, scene.cones[:, 4:])
    assert scene.cones[:, 2].min() == 0 and (scene.cones[:, [2, 6]] >= 0).all()  # above the field


def test_tree_is_haines_tree():
    scene = spd.tree(3)
    assert scene.view == nff.View((4.5, 0.4, 2.0), (0, 0, 1.5), (0, 0, 1), 45.0, 1.0, (512, 512))
    assert len(scene.lights) == 7
    from_c = [(0, 0, 0, 0.15, 0, 0, 1, 0.1005), (0, 0, 1, 0.1005, 0.417812, 0, 1.49793, 0.067335),
              (0.625853, 0.271578, 1.74586, 0.0451145, 0.594216, 0.406804, 1.98278, 0.0302267),
              (0.625853, 0.271578, 1.74586, 0.0451145, 0.864379, 0.382326, 1.88117, 0.0302267)]  # fmt: skip
    for i, row in zip((0, 1, 3, 4), from_c):
        assert scene.cones[i] == pytest.approx(row, abs=6e-6), i


# gears.c's header ("Total gears = SF**3: concave polygons = 2 * SF**3,
# rectangles = 4*TEETH * SF**3": 2, 16, 54, 128 faces and 144, 1152, 3888,
# 9216 rectangles at 1 to 4), and the ground; the README's 9345 at 4.
GEARS = {1: (2, 144), 2: (16, 1152), 3: (54, 3888), 4: (128, 9216)}


@pytest.mark.parametrize("size", sorted(GEARS))
def test_gears_counts_and_bounds(size):
    scene = spd.generate("gears", size)
    faces, rectangles = GEARS[size]
    sides = [len(p.vertices) for p in scene.polygons]
    assert sides.count(144) == faces and sides.count(4) == rectangles + 1 and len(sides) == faces + rectangles + 1
    points = np.concatenate([p.vertices for p in scene.polygons[1:]])
    assert np.abs(points[:, :2]).max() < 1.0 and points[:, 2].max() == 1.0 and points[:, 2].min() > 0.0
    glass = [f for f in scene.fills if f.t > 0]
    assert len(glass) == sum((x * 4 + y * 2 + z) % 5 == 0 for x in range(size) for y in range(size)
                             for z in range(size))  # fmt: skip
    assert all(max(f.color) == 1.0 for f in scene.fills[1:])


def test_gears_is_haines_gears():
    scene = spd.gears(2)
    assert scene.view == nff.View((-1.1, -2.1, 2.6), (0, 0, 0), (0, 0, 1), 45.0, 1.0, (512, 512))
    assert len(scene.lights) == 5
    assert scene.fills[0].color == (1.0, 0.85, 0.7) and scene.fills[0].ks == 0.6
    # the first gear's first tooth tip, as gears.c writes it at size 2
    assert scene.polygons[1].vertices[0] == pytest.approx((0.0227964, -0.504097, 1.0), abs=6e-7)
