"""NFF (raybench.formats.nff): every entity read as Haines's NFF.TXT defines
it, fills mapped to materials as docs/reference/nff.md says, a scene's
export read back as the same scene, and a malformed line named by its number."""

import math

import numpy as np
import pytest
from test_cli import assert_user_error, cli

from raybench import Camera, Light, Material, Scene
from raybench.errors import RaybenchError
from raybench.formats import nff, polygons

EVERY = """\
# every entity NFF has
v
from 2.1 1.3 1.7
at 0 0 0
up 0 0 1
angle 45
hither 0.01
resolution 64 48
b 0.078 0.361 0.753
l 4 3 2
l 1 -4 4 0.5 0.25 1   # a coloured light
f 1 0.75 0.33 0.8 0 100000 0 1
p 4
12 12 -0.5
-12 12 -0.5
-12 -12 -0.5
12 -12 -0.5
f 1 0.9 0.7 0.5 0.5 3.0827 0 1
s 0 0 0 0.5
s 0.272166 0.272166 0.544331 0.166667
pp 3
0 0 1 0 0 1
1 0 1 0 0.6 0.8
0 1 1 0.6 0 0.8
c
0 0 0 1
0 0 2 0.5
"""


def test_every_entity_is_read():
    got = nff.read(EVERY)
    assert got.counts() == {"spheres": 2, "polygons": 1, "patches": 1, "cones": 1}
    assert got.view == nff.View((2.1, 1.3, 1.7), (0.0, 0.0, 0.0), (0.0, 0.0, 1.0), 45.0, 0.01, (64, 48))
    assert got.background == (0.078, 0.361, 0.753)
    assert got.lights == [((4.0, 3.0, 2.0), None), ((1.0, -4.0, 4.0), (0.5, 0.25, 1.0))]
    assert got.fills == [nff.Fill((1.0, 0.75, 0.33), 0.8, 0.0, 100000.0, 0.0, 1.0),
                         nff.Fill((1.0, 0.9, 0.7), 0.5, 0.5, 3.0827, 0.0, 1.0)]  # fmt: skip
    assert got.sphere_fill.tolist() == [1, 1] and got.cone_fill.tolist() == [1]
    assert got.cones.tolist() == [[0, 0, 0, 1, 0, 0, 2, 0.5]]
    # the square is a fan of two triangles, the patch one, with its own normals, then the cone's
    tri = got.triangles()
    segments = polygons.CONE_SEGMENTS
    assert len(tri) == 3 + 2 * segments and tri.fill.tolist() == [0, 0, 1] + [1] * 2 * segments
    assert tri.corners[1].tolist() == [[12, 12, -0.5], [-12, -12, -0.5], [12, -12, -0.5]]
    assert np.allclose(tri.normals[0], [0, 0, 1])  # the polygon's own (Newell's)
    assert tri.normals[2].tolist() == [[0, 0, 1], [0, 0.6, 0.8], [0.6, 0, 0.8]]
    assert tri.smooth.tolist() == [False, False] + [True] * (1 + 2 * segments)
    assert got.notes() == []  # everything is drawn


def test_a_cone_on_one_line_as_the_spd_writes_it():
    got = nff.read("c 0 0 0 1 0 0 2 0.5\nc\n1 1 1 1\n1 1 3 0.5\n")
    assert got.cones.tolist() == [[0, 0, 0, 1, 0, 0, 2, 0.5], [1, 1, 1, 1, 1, 1, 3, 0.5]]


def test_the_scene_of_an_nff():
    scene = nff.read(EVERY).scene()
    assert len(scene) == 2
    # the polygon (flat), then the patch and the cone (smooth, one fill: one run), in the file's order
    assert [(len(m.mesh), m.mesh.normals is not None) for m in scene.meshes] == [(2, False), (1 + 64, True)]
    assert scene.traced().kind == "mixed" and len(scene.traced()) == 2 + 3 + 64
    floor_colour, floor_material = nff.Fill((1.0, 0.75, 0.33), 0.8, 0.0, 100000.0, 0.0, 1.0).material()
    assert scene.meshes[0].colour == pytest.approx(floor_colour) and scene.meshes[0].material == floor_material
    # angle is raybench's fov_deg: the full vertical field of view
    assert scene.camera == Camera((2.1, 1.3, 1.7), (0, 0, 0), (0, 0, 1), 45.0)
    assert scene.background == (0.078, 0.361, 0.753)
    share = math.sqrt(2) / 4  # Haines's relative intensity of each of 2 lights
    assert scene.ambient == pytest.approx((share,) * 3)
    assert scene.lights[0] == Light((4, 3, 2), (1, 1, 1), share)
    assert scene.lights[1].color == (0.5, 0.25, 1.0)
    assert scene.materials[0] == Material(specular=0.5, shininess=3.0827, reflect=0.5, ior=1.0)
    # Kd * rgb over what raybench's lighting leaves, 1 - Ks - T = 0.5: the rgb
    assert np.allclose(scene.colors, [[1, 0.9, 0.7]] * 2)


@pytest.mark.parametrize(
    "fill,colour,material",
    [
        # a plain diffuse fill: Kd scales the colour
        (nff.Fill((1.0, 0.75, 0.5), 0.8, 0.0, 100000.0, 0.0, 1.0), (0.8, 0.6, 0.4),
         Material(specular=0.0, shininess=1e4, ior=1.0)),
        # glass: Ks and T, the colour brightened by what is left for it
        (nff.Fill((0.5, 0.5, 0.5), 0.1, 0.1, 30.0, 0.8, 1.5), (0.5, 0.5, 0.5),
         Material(specular=0.1, shininess=30.0, reflect=0.1, transmit=0.8, ior=1.5)),
        # Ks + T over 1 is scaled to 1; nothing left for the diffuse colour
        (nff.Fill((0.2, 0.4, 0.6), 1.0, 1.0, 10.0, 1.0, 1.33), (0.2, 0.4, 0.6),
         Material(specular=0.5, shininess=10.0, reflect=0.5, transmit=0.5, ior=1.33)),
        # the colour clipped to 1; an index of refraction of 0 (tetra's) where nothing is transmitted
        (nff.Fill((1.0, 0.2, 0.2), 1.0, 0.5, 0.0, 0.0, 0.0), (1.0, 0.4, 0.4),
         Material(specular=0.5, shininess=0.0, reflect=0.5, ior=1.0)),
    ],
)  # fmt: skip
def test_the_fill_mapping(fill, colour, material):
    got_colour, got_material = fill.material()
    assert got_colour == pytest.approx(colour)
    assert got_material == material


def _scene() -> Scene:
    rng = np.random.default_rng(38)
    n = 40
    materials = [Material(specular=r, shininess=s, reflect=r, transmit=t, ior=i)
                 for r, s, t, i in zip(rng.uniform(0, 0.5, n), rng.uniform(1, 200, n), rng.uniform(0, 0.5, n),
                                       rng.uniform(1, 2, n))]  # fmt: skip
    lights = [Light((1, 9, -3), (1, 0.9, 0.8), 0.7), Light((-4, 2, 2), (0.2, 0.4, 1.0), 1.0)]
    camera = Camera((0.5, 1, -12), (0, 0.2, 3), (0, 1, 0), 38.5)
    return Scene(rng.normal(0, 3, (n, 3)), rng.uniform(0.1, 1, n), rng.uniform(0, 1, (n, 3)), camera,
                 materials=materials, lights=lights, background=(0.1, 0.2, 0.3))  # fmt: skip


def test_a_scene_exported_reads_back_the_same():
    scene = _scene()
    back = nff.read(nff.from_scene(scene).text()).scene()
    assert np.array_equal(back.spheres, scene.spheres)  # the same float32 bits
    assert back.camera == scene.camera and back.background == scene.background
    for a, b in zip(back.materials, scene.materials):
        assert a.to_dict() == pytest.approx(b.to_dict())
    assert len(back.lights) == 2
    for a, b in zip(back.lights, scene.lights):
        assert a.position == b.position
        assert np.multiply(a.color, a.intensity) == pytest.approx(np.multiply(b.color, b.intensity))


def test_an_export_keeps_the_mirrored_share_where_the_highlight_differs():
    """NFF has one Ks: a material whose highlight weight differs from its
    mirrored share comes back with the mirrored share for both."""
    scene = Scene([[0, 0, 5]], [1], [[0.5, 0.5, 0.5]], materials=[Material(specular=0.8, reflect=0.2)])
    back = nff.read(nff.from_scene(scene).text()).scene()
    assert back.materials[0] == Material(specular=0.2, reflect=0.2)
    assert back.camera is not None  # a fitted view: NFF needs one


def test_a_file_without_a_view_gets_a_camera_that_sees_it():
    scene = nff.read("s 10 0 0 1\ns -10 4 3 2\n").scene()
    camera = scene.camera
    forward = np.subtract(camera.look_at, camera.position)
    forward /= np.linalg.norm(forward)
    for c, r in zip(scene.centers, scene.radii):
        to = c - np.array(camera.position)
        angle = math.degrees(math.acos(to @ forward / np.linalg.norm(to)) + math.asin(r / np.linalg.norm(to)))
        assert angle < camera.fov_deg / 2


@pytest.mark.parametrize(
    "text,line,needle",
    [
        ("s 0 0 0 1\ns 0 0 x 1\n", 2, "'x' is not a number"),
        ("# a comment\n\ns 0 0 1\n", 3, "expected 4 numbers"),
        ("s 0 0 0 0\n", 1, "radius must not be 0"),
        ("s 0 0 0 nan\n", 1, "not finite"),
        ("q 1 2 3\n", 1, "unknown entity 'q'"),
        ("p 2\n0 0 0\n1 0 0\n", 1, "at least 3 vertices"),
        ("p 3\n0 0 0\n1 0 0\n", 1, "ends after 2 of its 3 vertices"),
        ("pp 3\n0 0 0 0 0 1\n1 0 0 0 0 1\n0 1 0 0 1\n", 4, "pp (polygon patch) vertex 3"),
        ("p three\n", 1, "vertex count"),
        ("c\n0 0 0 1\n", 1, "before the cone's apex line"),
        ("c 0 0 0 1\n0 0 1 1\n", 1, "or all 8 numbers"),
        ("f 1 1 1 1 0 0 0\n", 1, "expected 8 numbers"),
        ("b 2 0 0\n", 1, "in [0, 1]"),
        ("l 1 2\n", 1, "expected 3 or 6 numbers"),
        ("v\nfrom 0 0 0\nat 0 0 1\nup 0 1 0\nhither 1\n", 1, "no 'angle' line"),
        ("v\nfrom 0 0 0\nat 0 0 1\nup 0 0 1\nangle 45\n", 1, "camera.up"),
        ("v\nfrom 0 0 0\nat 0 0 1\nup 0 1 0\nangle 45\nresolution 0 4\n", 6, "resolution"),
        ("v\nfrom 0 0 0\nat 0 0 1\nup 0 1 0\nangle 45\nv\n", 6, "a second view"),
        ("l 0 0 0\n" * 65, 65, "more than 64 lights"),
    ],
)
def test_a_malformed_line_is_named(text, line, needle):
    with pytest.raises(RaybenchError) as caught:
        nff.read(text, "bad.nff")
    message = str(caught.value)
    assert message.startswith(f"bad.nff: line {line}: "), message
    assert needle in message and "\n" not in message


def test_a_scene_with_meshes_exported_reads_back_the_same():
    """Meshes go out as polygons of three vertices (patches where they have normals) and come
    back as the same triangles in the same order, with their colours and materials."""
    import trimesh

    from raybench import SceneMesh
    from raybench.meshes import Mesh

    ball = trimesh.creation.icosphere(subdivisions=1)
    smooth = Mesh(ball.vertices.astype(np.float32), ball.faces.astype(np.int32),
                  ball.vertex_normals.astype(np.float32))  # fmt: skip
    flat = Mesh(np.array([[-5, -1, -5], [5, -1, -5], [5, -1, 5], [-5, -1, 5]], np.float32),
                np.array([[0, 1, 2], [0, 2, 3]], np.int32))  # fmt: skip
    glass = Material(transmit=0.9, ior=1.5)
    scene = _scene().replaced(meshes=[SceneMesh(flat, (0.8, 0.6, 0.2)), SceneMesh(smooth, (1.0, 1.0, 1.0), glass)])
    back = nff.read(nff.from_scene(scene).text()).scene()
    assert np.array_equal(back.spheres, scene.spheres)
    assert np.array_equal(back.triangles, scene.triangles)  # corners, colours and normals: the same float32 bits
    assert back.triangle_materials == scene.triangle_materials


def test_render_an_nff_draws_all_of_it(capsys, tmp_path):
    path = tmp_path / "every.nff"
    path.write_text(EVERY)
    code, out, err = cli(capsys, "render", "--scene", path, "--size", "40x30", "--device", "cpu", "--threads", 1,
                         "-o", tmp_path / "every.png")  # fmt: skip
    assert code == 0, err
    lines = out.splitlines()
    assert not any(line.startswith("note: read") for line in lines)
    assert "2 spheres and 67 triangles" in lines[-1] and (tmp_path / "every.png").exists()
    assert ": 40x30, " in lines[-1]
    # without --size, the view's own resolution
    code, out, err = cli(capsys, "render", "--scene", path, "--device", "cpu", "--threads", 1, "-o",
                         tmp_path / "own.png")  # fmt: skip
    assert code == 0, err
    assert ": 64x48, " in out.splitlines()[-1]


def test_a_malformed_nff_is_one_line_and_exit_2(capsys, tmp_path):
    path = tmp_path / "bad.nff"
    path.write_text("s 0 0 0 1\nf 1 1\n")
    code, out, err = cli(capsys, "render", "--scene", path, "--size", "40x30", "-o", tmp_path / "x.png")
    assert_user_error(code, out, err, "bad.nff: line 2: f (fill")
    assert not (tmp_path / "x.png").exists()


def test_export_on_the_command_line(capsys, tmp_path):
    source = tmp_path / "scene.json"
    _scene().save(source)
    target = tmp_path / "scene.nff"
    code, out, err = cli(capsys, "scene", "nff", "--scene", source, "-o", target)
    assert code == 0, err
    assert out.startswith(f"wrote {target}: 40 spheres from {source}: 40 spheres")
    assert np.array_equal(nff.load(target).scene().spheres, _scene().spheres)
    code, out, err = cli(capsys, "scene", "nff", "--scene", source, "-o", tmp_path / "scene.txt")
    assert_user_error(code, out, err, "must be a .nff file")
