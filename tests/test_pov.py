"""POV-Ray scene files (raybench.formats.pov): what is written, read back (the spheres, the
triangles, the camera's values, the depth, the lights, the materials); the command's errors;
and, where POV-Ray is installed, its picture of a small scene against raybench's."""

import math
import os
import re
import shutil
import subprocess

import numpy as np
import pytest
from test_cli import assert_user_error, cli

import raybench
from raybench import Camera, Scene, lighting
from raybench.formats import pov, spd

NUMBER = r"-?[0-9.e+-]+"


def vector(text: str, key: str) -> list[float]:
    """The <x, y, z> after `key` on its line."""
    m = re.search(rf"^\s*{key} <({NUMBER}), ({NUMBER}), ({NUMBER})>", text, flags=re.M)
    assert m, key
    return [float(v) for v in m.groups()]


def three_spheres() -> Scene:
    """Red, green and blue spheres, not in a mirror's symmetry, the green one a mirror, one light,
    a grey background: a picture that shows the handedness, the field of view and the materials."""
    centres = [(-1.6, 0.0, 5.0), (0.0, 0.3, 6.0), (1.7, -0.2, 5.5)]
    colours = [(0.9, 0.1, 0.1), (0.1, 0.9, 0.1), (0.1, 0.1, 0.9)]
    mirror = lighting.Material(specular=0.4, shininess=20.0, reflect=0.4)
    camera = Camera(position=(0.0, 0.5, 0.0), look_at=(0.0, 0.0, 5.0), up=(0.0, 1.0, 0.0), fov_deg=50.0)
    return Scene(centres, [0.8, 0.9, 0.7], colours, camera, materials=[lighting.MATTE, mirror, lighting.MATTE],
                 lights=[lighting.Light((3.0, 6.0, 0.0))], background=(0.3, 0.3, 0.3))  # fmt: skip


def test_the_horizontal_angle():
    assert pov.horizontal_angle(60.0, 100, 100) == pytest.approx(60.0)
    # tan(30 deg) * 1.6 = 0.923760, atan of it 42.7305 deg, twice that
    assert pov.horizontal_angle(60.0, 1680, 1050) == pytest.approx(85.4611, abs=1e-3)


def test_the_spheres_camera_lights_and_depth_read_back():
    scene = three_spheres()
    text = pov.text(scene, 1680, 1050, depth=3)
    assert len(re.findall(r"^sphere \{", text, flags=re.M)) == 3
    assert vector(text, "location") == [0.0, 0.5, 0.0]
    assert vector(text, "look_at") == [0.0, 0.0, 5.0]
    assert vector(text, "sky") == [0.0, 1.0, 0.0]
    assert vector(text, "right") == [-1.6, 0.0, 0.0]  # right-handed: right along -x
    angle = float(re.search(rf"angle ({NUMBER})", text)[1])
    assert angle == pytest.approx(2 * math.degrees(math.atan(math.tan(math.radians(25.0)) * 1.6)), abs=1e-6)
    assert "max_trace_level 4" in text  # POV-Ray counts the primary ray as a level
    assert len(re.findall(r"^light_source", text, flags=re.M)) == 1
    assert "background { rgb <0.3, 0.3, 0.3> }" in text
    # three looks: each sphere its own colour
    assert len(re.findall(r"^#declare T\d+ = texture", text, flags=re.M)) == 3
    assert "reflection { rgb 0.4 } }" in text and "phong 0.4 phong_size 20" in text
    assert "ambient rgb <0.06, 0.06, 0.06> diffuse 0.6" in text  # the mirror's colour lit by what is left of it


def test_the_balls_floor_is_two_triangles_and_its_spheres_are_all_there():
    nff = spd.balls(2)
    text = pov.from_nff(nff, 512, 512)
    assert len(re.findall(r"^sphere \{", text, flags=re.M)) == 91
    assert re.search(r"face_indices \{ 2, <0, 1, 2>, <3, 4, 5> \}", text)
    assert re.search(r"vertex_vectors \{ 6, <12, 12, -0.5>", text)
    assert "normal_vectors" not in text  # a polygon is flat: no patch's normals
    assert "angle 45" in text  # a square picture: the horizontal angle is the vertical one
    assert len(re.findall(r"^light_source", text, flags=re.M)) == 3


def test_a_scene_without_meshes_has_no_mesh2():
    assert "mesh2" not in pov.text(three_spheres(), 64, 40)


def test_cones_are_povrays_own_and_concave_faces_are_cut():
    rings = pov.from_nff(spd.rings(1), 320, 200)
    assert len(re.findall(r"^cone \{ .* open texture", rings, flags=re.M)) == 30  # as NFF: no caps
    assert "mesh2" in rings and rings.count("mesh2") == 1  # the wall
    gears = pov.from_nff(spd.gears(1), 320, 200)
    # two toothed faces of 144 vertices (142 triangles each however they are cut), 144 side
    # rectangles and the ground square
    faces = [int(n) for n in re.findall(r"face_indices \{ (\d+), ", gears)]
    assert sum(faces) == 2 * 142 + 144 * 2 + 2


def test_the_command_writes_a_pov_file(capsys, tmp_path):
    nff_path, out = tmp_path / "b.nff", tmp_path / "b.pov"
    spd.balls(1).save(nff_path)
    code, stdout, _ = cli(capsys, "scene", "pov", "--scene", nff_path, "-o", out, "--size", "320x200")
    assert code == 0 and "10 spheres, 1 polygon from" in stdout and "320x200, depth 5" in stdout
    assert "// povray +Ib.pov +W320 +H200 -A" in out.read_text()
    # no --size: the NFF's own resolution
    cli(capsys, "scene", "pov", "--scene", nff_path, "-o", out)
    assert "+W512 +H512" in out.read_text()


@pytest.mark.parametrize(
    ("args", "needle"),
    [(["-o", "x.png"], "must be a .pov file"), (["-o", "x.pov", "--depth", "99"], "depth"),
     (["-o", "x.pov", "--size", "0x5"], "size"), ([], "-o")],
)  # fmt: skip
def test_the_command_refuses_in_one_line(capsys, tmp_path, monkeypatch, args, needle):
    monkeypatch.chdir(tmp_path)
    spd.balls(1).save(tmp_path / "b.nff")
    assert_user_error(*cli(capsys, "scene", "pov", "--scene", "b.nff", *args), needle)


def test_povray_renders_the_picture_raybench_renders(tmp_path):
    if shutil.which("povray") is None:
        pytest.skip("povray is not installed (Debian: apt-get install povray): POV-Ray's picture is not checked")
    from PIL import Image

    scene, width, height = three_spheres(), 96, 60
    (tmp_path / "s.pov").write_text(pov.text(scene, width, height))
    done = subprocess.run([*pov.command("s.pov", width, height, 1), "+Os.png"], cwd=tmp_path, capture_output=True,
                          text=True, timeout=120)  # fmt: skip
    assert done.returncode == 0, done.stderr[-2000:]
    theirs = np.asarray(Image.open(tmp_path / "s.png").convert("RGB")).astype(int)
    frame = raybench.render(scene, width=width, height=height, device="cpu", shading="whitted")
    shown = np.abs(theirs - 77).max(axis=2) > 2  # the background: 0.3 of 255, rounded
    assert np.mean(shown == (frame.hits >= 0)) > 0.99
    both = shown & (frame.hits >= 0)
    assert np.mean(theirs[both].argmax(axis=1) == frame.image[both].argmax(axis=1)) > 0.99  # each sphere in its place
    assert np.abs(theirs - frame.image.astype(int)).mean() < 2.0


def test_glass_wears_its_interior_on_the_object(tmp_path):
    """POV-Ray's interior belongs to an object, not to a declared texture: a glass sphere, a
    glass mesh and a glass cone each say it where POV-Ray parses it (SPD mount's glass spheres
    failed to parse once)."""
    glass = lighting.Material(specular=0.1, shininess=50.0, reflect=0.1, transmit=0.8, ior=1.5)
    ball = Scene([(0.0, 0.0, 5.0)], [1.0], [(1.0, 1.0, 1.0)], Camera(), materials=[glass],
                 lights=[lighting.Light((3.0, 6.0, 0.0))])  # fmt: skip
    text = pov.text(ball, 64, 40)
    assert "#declare I0 = interior { ior 1.5 }" in text and "texture { T0 } interior { I0 }" in text
    assert not re.search(r"#declare T\d+ = .*interior", text)
    mount = pov.from_nff(spd.generate("mount", 1), 64, 40)
    if shutil.which("povray") is None:
        if os.environ.get("RAYBENCH_REQUIRE_POVRAY") == "1":
            pytest.fail("povray is not installed; RAYBENCH_REQUIRE_POVRAY=1 requires POV-Ray's parse checked")
        pytest.skip("povray is not installed (Debian: apt-get install povray): POV-Ray's parse is not checked")
    for name, body in (("ball", text), ("mount", mount)):
        (tmp_path / f"{name}.pov").write_text(body)
        done = subprocess.run([*pov.command(f"{name}.pov", 64, 40, 1), f"+O{name}.png"], cwd=tmp_path,
                              capture_output=True, text=True, timeout=120)  # fmt: skip
        assert done.returncode == 0, done.stderr[-2000:]
