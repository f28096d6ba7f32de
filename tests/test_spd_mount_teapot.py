"""The SPD's mount and teapot generators (raybench.formats.spd_mount,
spd_teapot): primitive counts against the figures in the SPD's own
documentation, bounds and shape, and spot values from the output of
Haines's C programs.

The values "from C" below are lines of the NFF that mount.c and teapot.c
(erich666/StandardProceduralDatabases at 5c860e2, compiled with gcc 12.2 on
x86-64 Linux, run as `mount -s N` and `teapot -s N`) write, to their 6
significant digits (%g); a geometry line is x y z (and a patch's normal)."""

import numpy as np
import pytest
from test_cli import assert_user_error, cli

from raybench.errors import RaybenchError
from raybench.formats import nff, spd, spd_mount, spd_teapot


def from_c(line: str) -> list[float]:
    return [float(w) for w in line.split()]


def assert_as_c(ours, line: str, what=""):
    """ours agrees with the C's %g line to its 6 significant digits (a
    value the C writes as 1e-16 or so is a rounding of 0)."""
    assert np.asarray(ours).reshape(-1).tolist() == pytest.approx(from_c(line), rel=6e-6, abs=1e-9), what


# mount.c's header ("Total triangular polygons = 2 * (4**size_factor)": 8,
# 32, 128 at 1 to 3, 8192 at 6; 4 spheres at every size); the README's
# table gives mount 8196 primitives at the default size 6.
MOUNT = {1: 8, 2: 32, 3: 128, 4: 512, 5: 2048, 6: 8192}


@pytest.mark.parametrize("size", sorted(MOUNT))
def test_mount_counts_and_bounds(size):
    scene = spd.generate("mount", size)
    assert scene.counts() == {"spheres": 4, "polygons": MOUNT[size], "patches": 0, "cones": 0}
    corners = np.array([p.vertices for p in scene.polygons])
    assert corners.shape == (MOUNT[size], 3, 3)
    # the grid: x and y on 2**size + 1 evenly spaced lines from -1 to 1
    n = 2**size
    assert np.unique(corners[..., :2]) == pytest.approx(np.linspace(-1.0, 1.0, n + 1))
    # one height at each grid point, whichever triangle has it, 0 at the square's corners
    points = {}
    for x, y, z in corners.reshape(-1, 3).tolist():
        assert points.setdefault((x, y), z) == z
    assert len(points) == (n + 1) ** 2
    assert [points[(x, y)] for x in (-1.0, 1.0) for y in (-1.0, 1.0)] == [0.0] * 4
    # every triangle counter-clockwise from above, so facing up
    up = np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 1])[:, 2]
    assert (up > 0).all()
    assert all(p.fill == 1 for p in scene.polygons) and (scene.sphere_fill == 0).all()


def test_mount_crystal_spheres_touch_in_a_pyramid():
    s = spd.mount(1).spheres
    assert (s[:, 3] == 0.17).all()
    assert s[:, :3].mean(axis=0) == pytest.approx((-0.8, 0.8, 1.0))  # about the pyramid's centre
    gaps = [np.linalg.norm(s[i, :3] - s[j, :3]) for i in range(4) for j in range(i + 1, 4)]
    assert gaps == pytest.approx([2 * 0.17] * 6)  # each touching the other three


def test_mount_is_haines_mount():
    """The view, light, fills and spheres mount.c writes at size 1, and
    triangles of its output at sizes 1, 6 and 8 (past 7, where the C's
    hash shifts by a negative count), in its order."""
    scene = spd.mount(1)
    assert scene.view == nff.View((-1.6, 1.6, 1.7), (0, 0, 0), (0, 0, 1), 45.0, 0.01, (512, 512))
    assert scene.background == (0.078, 0.361, 0.753) and scene.lights == [((-100.0, -100.0, 100.0), None)]
    glass, rock = scene.fills
    assert (glass.color, glass.kd, glass.ks, glass.t, glass.ior) == ((1, 1, 1), 0.1, 0.1, 0.9, 1.5)
    assert glass.shine == pytest.approx(101.148, abs=5e-4)  # "f 1 1 1 0.1 0.1 101.148 0.9 1.5"
    assert rock == nff.Fill((0.5, 0.45, 0.35), 1.0, 0.0, 100000.0, 0.0, 0.0)
    spheres = ["-0.8 0.8 1.20821 0.17", "-0.661196 0.661196 0.930598 0.17", "-0.749194 0.98961 0.930598 0.17",
               "-0.98961 0.749194 0.930598 0.17"]  # fmt: skip
    for ours, line in zip(scene.spheres, spheres):
        assert_as_c(ours, line)
    first = ["-1 -1 0", "0 -1 -0.5481", "0 0 0.529551"]  # mount -s 1, the first triangle
    assert_as_c(scene.polygons[0].vertices, " ".join(first))
    triangles = {
        (6, 0): ["-1 -1 0", "-0.96875 -1 -0.0160409", "-0.96875 -0.96875 -0.00732202"],
        (6, 4097): ["0.03125 0.03125 0.505092", "0 0.03125 0.520233", "0 0 0.529551"],
        (6, 8191): ["-0.96875 1 0.0324693", "-1 1 0", "-1 0.96875 0.0514796"],
        (8, 77777): ["0.804688 0.242188 -0.454616", "0.796875 0.242188 -0.452409", "0.796875 0.234375 -0.434985"],
        (8, 131071): ["-0.992188 1 0.0078648", "-1 1 0", "-1 0.992188 0.0136603"],
    }
    made = {size: spd_mount.mountain(size) for size in (6, 8)}
    for (size, i), lines in triangles.items():
        assert_as_c(made[size][i], " ".join(lines), (size, i))


def test_mount_deviates_are_gaussian():
    """The 65,536 deviates the mountain draws on are a standard normal's."""
    table = spd_mount._gauss_table()
    # a rejected pair steps on along the generator's sequence, where other
    # seeds may already be: some seeds share a deviate, most do not
    assert len(np.unique(table)) > 50000
    assert abs(table.mean()) < 0.02 and table.std() == pytest.approx(1.0, abs=0.02)
    assert (np.abs(table) < 1.0).mean() == pytest.approx(0.6827, abs=0.01)


def test_mount_hash_past_size_7():
    """Past 7 the hash's last shift is negative: that term is 0 (as the C
    compiled on x86-64 gives it), the others as at 7."""
    a, b = np.arange(300), np.arange(300)[::-1]
    assert (spd_mount.grid_hash(a, b, 8) == (((a << 15) + (b << 7)) & 0xFFFF)).all()
    assert (spd_mount.grid_hash(a, b, 7) == (((a << 16) + (b << 8) + a) & 0xFFFF)).all()


# teapot.c's header ("Total patches = 32*2*n*n - 8*n", "Total squares =
# n*n": 56, 240, 552 patches and 1, 4, 9 squares at 1 to 3, 9120 and 144 at
# 12); the README's table gives teapot 9264 primitives, which is size 12.
TEAPOT = {1: (56, 1), 2: (240, 4), 3: (552, 9), 4: (992, 16), 6: (2256, 36), 12: (9120, 144)}


@pytest.mark.parametrize("size", sorted(TEAPOT))
def test_teapot_counts_and_bounds(size):
    scene = spd.generate("teapot", size)
    patches, squares = TEAPOT[size]
    assert patches == 32 * 2 * size**2 - 8 * size
    assert scene.counts() == {"spheres": 0, "polygons": squares, "patches": patches, "cones": 0}
    board = [p for p in scene.polygons if p.normals is None]
    assert [p.fill for p in board] == [0] * (squares // 2) + [1] * (squares - squares // 2)  # white, then grey
    quads = np.array([p.vertices for p in board])
    assert quads.shape == (squares, 4, 3) and (quads[..., 2] == 0).all()
    assert np.abs(quads[..., :2]).max() == 4.0 and len(np.unique(quads[..., :2])) == size + 1
    pots = [p for p in scene.polygons if p.normals is not None]
    corners = np.array([p.vertices for p in pots])
    normals = np.array([p.normals for p in pots])
    assert corners.shape == normals.shape == (patches, 3, 3) and all(p.fill == 2 for p in pots)
    # a Bezier patch lies within its control points' box; every normal a unit vector
    lo, hi = spd_teapot.VERTICES.min(axis=0), spd_teapot.VERTICES.max(axis=0)
    assert (corners >= lo - 1e-12).all() and (corners <= hi + 1e-12).all()
    assert np.linalg.norm(normals, axis=-1) == pytest.approx(np.ones((patches, 3)))
    # at most one corner of a triangle at a cusp, where the normal is straight up (lid) or down (bottom)
    on_axis = (np.abs(corners[..., 0]) <= 1e-4) & (np.abs(corners[..., 1]) <= 1e-4)
    assert on_axis.sum(axis=1).max() == 1 and on_axis.sum() == 8 * size
    assert sorted({tuple(n) for n in normals[on_axis].tolist()}) == [(0, 0, -1), (0, 0, 1)]


def test_teapot_body_faces_out():
    """The body's eight patches' normals point away from the teapot's axis."""
    points, normals = spd_teapot.surface(4)
    radial = np.einsum("...i,...i->...", normals[4:12, ..., :2], points[4:12, ..., :2])
    assert (radial > 1.0).all()


def test_teapot_is_haines_teapot():
    """The view, lights, fills and board teapot.c writes at size 2, and
    patches of its output at sizes 2 (the first, and triangles at the lid's
    and the bottom's cusp) and 12, in its order."""
    scene = spd.teapot(2)
    assert scene.view == nff.View((4.86, 7.2, 5.4), (0, 0, 0), (0, 0, 1), 45.0, 1.0, (512, 512))
    assert [p for p, _ in scene.lights] == [(-3.1, 9.8, 12.1), (11.3, 5.1, 8.8)]
    white, grey, orange = scene.fills
    assert (white.color, grey.color, orange.color) == ((1, 1, 1), (0.5, 0.5, 0.5), (1, 0.5, 0.1))
    assert (white.kd, white.ks, orange.kd, orange.ks) == (0.5, 0.5, 0.75, 0.25)
    assert white.shine == pytest.approx(4.81884, abs=5e-6) and orange.shine == pytest.approx(3.0827, abs=5e-5)
    # "p 4" after the white fill: its first square, then the grey's first
    assert_as_c(scene.polygons[0].vertices, "-4 0 0 0 0 0 0 4 0 -4 4 0")
    assert_as_c(scene.polygons[2].vertices, "-4 -4 0 0 -4 0 0 0 0 -4 0 0")
    patches = {
        (2, 0): ["1.4 0 2.4 -0.902861 -0 -0.429934", "0.994 -0.994 2.4 -0.637936 0.637936 -0.431366",
                 "0.996219 -0.996219 2.49844 1.4538e-15 -1.67359e-15 1"],
        (2, 160): ["0.231031 -0.231031 2.98125 0.550896 -0.550896 -0.626919",
                   "0.325 0 2.98125 0.780869 0 -0.624695", "0 0 3.15 0 0 1"],
        (2, 216): ["0.911906 0.911906 0.046875 0.0996006 0.0996006 -0.99003",
                   "1.28438 0 0.046875 0.141421 0 -0.989949", "0 0 0 0 0 -1"],
        (12, 5000): ["2.4679 0.369136 1.22016 0.627607 0.733748 -0.260237",
                     "2.43673 0.403742 1.28186 0.450382 0.888095 -0.0918861",
                     "2.51615 0.368795 1.42502 0.500852 0.865404 -0.0149303"],
        (12, 9119): ["1.5 0 0.15 1 0 0", "1.48653 -0.205972 0.15 0.99137 -0.13109 -6.11468e-17",
                     "1.48425 -0.205656 0.131293 0.952941 -0.126009 -0.275728"],
    }  # fmt: skip
    made = {size: spd_teapot.tessellate(size) for size in (2, 12)}
    for (size, i), lines in patches.items():
        corners, normals = made[size]
        assert_as_c(np.concatenate([corners[i], normals[i]], axis=1), " ".join(lines), (size, i))


def test_mount_and_teapot_read_back():
    for scene in (spd.mount(2), spd.teapot(3)):
        back = nff.read(scene.text())
        assert back.counts() == scene.counts() and back.view == scene.view
        ours = np.concatenate([p.vertices for p in scene.polygons])
        assert np.allclose(np.concatenate([p.vertices for p in back.polygons]), ours, rtol=1e-8, atol=1e-9)
        assert len(back.triangles()) == sum(len(p.vertices) - 2 for p in scene.polygons)


@pytest.mark.parametrize("name,size", [("mount", 0), ("mount", 11), ("teapot", 0), ("teapot", 101)])
def test_mount_and_teapot_sizes_out_of_range_are_refused(name, size):
    with pytest.raises(RaybenchError):
        spd.generate(name, size)


def test_mount_and_teapot_on_the_command_line(capsys, tmp_path):
    target = tmp_path / "mount.nff"
    code, out, err = cli(capsys, "scene", "spd", "mount", "--size", 2, "-o", target)
    assert code == 0, err
    assert out == f"wrote {target}: SPD mount at size factor 2: 4 spheres, 32 polygons\n"
    target = tmp_path / "teapot.nff"
    code, out, err = cli(capsys, "scene", "spd", "teapot", "--size", 2, "-o", target)
    assert code == 0, err
    assert out == f"wrote {target}: SPD teapot at size factor 2: 4 polygons, 240 patches\n"
    assert nff.load(target).counts()["patches"] == 240
    code, out, err = cli(capsys, "scene", "spd", "teapot", "--size", 101, "-o", target)
    assert_user_error(code, out, err, "--size", "from 1 to 100")


def test_the_default_sizes_are_the_programs():
    """mount.c's and teapot.c's own default size factor, 6 (teapot's README
    figure, 9,264 primitives, is at 12)."""
    assert spd.SCENES["mount"][1] == spd.SCENES["teapot"][1] == 6
    assert sum(spd.generate("mount").counts().values()) == 8196
