"""The SPD's mount generator (raybench.formats.spd_mount): primitive
counts against the figures in the SPD's own documentation, bounds and
shape, and spot values from the output of Haines's C program.

The values "from C" below are lines of the NFF that mount.c
(erich666/StandardProceduralDatabases at 5c860e2, compiled with gcc 12.2 on
x86-64 Linux, run as `mount -s N`) writes, to its 6 significant digits
(%g); a geometry line is x y z."""

import numpy as np
import pytest
from test_cli import cli

from raybench.errors import RaybenchError
from raybench.formats import nff, spd, spd_mount


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


def test_mount_and_teapot_read_back():
    for scene in (spd.mount(2),):
        back = nff.read(scene.text())
        assert back.counts() == scene.counts() and back.view == scene.view
        ours = np.concatenate([p.vertices for p in scene.polygons])
        assert np.allclose(np.concatenate([p.vertices for p in back.polygons]), ours, rtol=1e-8, atol=1e-9)
        assert len(back.triangles()) == sum(len(p.vertices) - 2 for p in scene.polygons)


@pytest.mark.parametrize("name,size", [("mount", 0), ("mount", 11)])
def test_mount_and_teapot_sizes_out_of_range_are_refused(name, size):
    with pytest.raises(RaybenchError):
        spd.generate(name, size)


def test_mount_and_teapot_on_the_command_line(capsys, tmp_path):
    target = tmp_path / "mount.nff"
    code, out, err = cli(capsys, "scene", "spd", "mount", "--size", 2, "-o", target)
    assert code == 0, err
    assert out == f"wrote {target}: SPD mount at size factor 2: 4 spheres, 32 polygons\n"


def test_the_default_sizes_are_the_programs():
    """mount.c's own default size factor, 6."""
    assert spd.SCENES["mount"][1] == 6
    assert sum(spd.generate("mount").counts().values()) == 8196
