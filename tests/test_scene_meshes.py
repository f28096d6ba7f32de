"""Scene format version 3: meshes beside spheres, from a file relative to
the scene file or inline, placed by a transform, in a colour and a
material; saved inline and loaded again bit for bit; traced through the
one render path (a mesh scene's triangles); and each bad input one line,
exit 2, nothing written. Only one test traces (the triangle kernels
compile for each process)."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
import trimesh
from PIL import Image

from raybench import Material, Renderer, Scene, render
from raybench.cli import run
from raybench.meshes import Mesh
from raybench.scene_meshes import SceneMesh, Transform

TRIANGLE = {"vertices": [[0, 0, 0], [1, 0, 0], [0, 1, 0]], "faces": [[0, 1, 2]]}


def doc(*meshes, **top):
    return {"format": "raybench-scene", "version": 3, "meshes": list(meshes), **top}


def write(path, document) -> str:
    path.write_text(json.dumps(document))
    return str(path)


def box_file(folder, name="box.ply"):
    """A box of 12 triangles, 2 x 1 x 1 about the origin, as a PLY file."""
    (folder / "models").mkdir(exist_ok=True)
    trimesh.creation.box(extents=(2.0, 1.0, 1.0)).export(folder / "models" / name)
    return f"models/{name}"


def test_transform_scales_then_rotates_x_y_z_then_translates():
    """The stated order: (1, 0, 0) scaled by 2 is (2, 0, 0); turned 90
    degrees about z it is (0, 2, 0); then moved by (1, 2, 3)."""
    entry = {**TRIANGLE, "transform": {"scale": 2, "rotate": [0, 0, 90], "translate": [1, 2, 3]}}
    scene = Scene.from_dict(doc(entry))
    corners = scene.triangles[:9, 0].reshape(3, 3)
    assert corners.tolist() == [[1, 2, 3], [1, 4, 3], [-1, 2, 3]]
    # each axis in turn, right-handed: y to z about x, z to x about y
    turn = Transform(rotate=(90, 90, 0)).linear()
    assert np.allclose(turn @ [0, 1, 0], [1, 0, 0]) and np.allclose(turn @ [0, 0, 1], [0, -1, 0])
    assert np.allclose(Transform(scale=(1, 2, 3)).linear(), np.diag([1, 2, 3]))
    assert np.allclose(Transform(rotate=(0, 0, 30)).linear()[0, :2], [math.sqrt(3) / 2, -0.5])


def test_a_file_relative_to_the_scene_and_an_inline_mesh_load_save_and_load_again(tmp_path):
    """A mesh file's path is the scene file's folder's; the scene holds one
    triangle buffer (the file's 12, then the inline one), colours and
    materials a triangle; a saved scene holds its meshes placed and inline,
    and loads again with the same bits, wherever it is saved."""
    inline = {**TRIANGLE, "color": [1, 0, 0], "material": {"reflect": 0.5}}
    placed = {"file": box_file(tmp_path), "transform": {"translate": [0, 0, 5]}, "color": [0.2, 0.4, 0.6]}
    path = write(tmp_path / "scene.json", doc(placed, inline, spheres=[]))
    scene = Scene.load(path)
    assert scene.version == 3 and len(scene) == 0 and scene.summary == "13 triangles"
    assert scene.triangles.shape == (12, 13) and scene.triangles[2, :12].min() == 4.5
    assert scene.triangles[9:12, 12].tolist() == [1, 0, 0] and np.allclose(scene.triangles[9:12, 0], [0.2, 0.4, 0.6])
    materials = scene.triangle_materials
    assert len(materials) == 13 and materials[0] == Material() and materials[12] == Material(reflect=0.5)
    traced = scene.traced()
    assert traced.kind == "triangle" and traced.leaves is scene.triangles and len(traced) == 13
    (tmp_path / "elsewhere").mkdir()
    scene.save(tmp_path / "elsewhere" / "copy.json")
    again = Scene.load(tmp_path / "elsewhere" / "copy.json")
    assert again.triangles.tobytes() == scene.triangles.tobytes() and again.triangle_materials == materials
    assert "file" not in json.loads((tmp_path / "elsewhere" / "copy.json").read_text())["meshes"][0]


def test_versions_1_and_2_are_as_before_and_smooth_normals_mix_with_flat():
    """A scene without meshes stays version 1 or 2 and traces its spheres;
    a mesh with normals beside one without gives the latter zero normals
    (its plane's, in the triangle's surface)."""
    plain = Scene([[0, 0, 5]], [1], [[1, 1, 1]])
    assert plain.version == 1 and plain.triangles is None and plain.traced().kind == "sphere"
    assert plain.traced().leaves is plain.spheres and "meshes" not in plain.to_dict()
    smooth = {**TRIANGLE, "normals": [[0, 0, 2], [0, 0, 1], [0, 0, 1]]}
    scene = Scene.from_dict(doc(smooth, TRIANGLE))
    assert scene.triangles.shape == (21, 2) and scene.triangles[12:, 1].tolist() == [0] * 9
    assert scene.triangles[12:15, 0].tolist() == [0, 0, 1]  # made unit length


def test_spheres_and_meshes_in_one_scene_are_traced_as_the_mixed_kind():
    """A scene of both is traced as one buffer of both kinds (test_mixed.py
    renders it): the spheres' columns, then the triangles', and their
    materials in that order, matte where a kind gives none."""
    glass = Material(transmit=0.9, ior=1.5)
    sphere = {"center": [0, 0, 5], "radius": 1, "color": [1, 1, 1], "material": glass.to_dict()}
    both = Scene.from_dict({**doc(TRIANGLE), "version": 3, "spheres": [sphere]})
    assert both.summary == "1 spheres and 1 triangles"
    traced = both.traced()
    assert traced.kind == "mixed" and len(traced) == 2 and traced.noun == "primitives"
    assert traced.leaves[:7, 0].tolist() == both.spheres[:, 0].tolist()
    assert traced.leaves[:12, 1].tolist() == both.triangles[:, 0].tolist()
    assert traced.leaves[-1].tolist() == [0, 1]  # the tags: a sphere, a triangle
    assert traced.materials[0] == glass and traced.materials[1] == Material()


NAN_VERTEX = '{"format": "raybench-scene", "version": 3, "meshes": [{"vertices": [[NaN, 0, 0], [1, 0, 0], [0, 1, 0]], "faces": [[0, 1, 2]]}]}'  # noqa: E501


@pytest.mark.parametrize(
    "document, message",
    [
        (doc({"file": "missing.ply"}), r"meshes\[0\]\.file: .*missing\.ply: no such file"),
        (doc({**TRIANGLE, "faces": [[0, 1, 3]]}), r"meshes\[0\]: face 0 has vertex index \[0, 1, 3\], out of range"),
        (NAN_VERTEX, r"meshes\[0\]: vertex 0 has a non-finite coordinate"),
        (doc({**TRIANGLE, "faces": []}), r"meshes\[0\]: no faces"),
        (doc({**TRIANGLE, "transform": {"shear": 1}}), r"meshes\[0\]\.transform\.shear: unknown field"),
        (doc({**TRIANGLE, "transform": {"scale": 0}}), r"meshes\[0\]\.transform\.scale: each factor must be > 0"),
        (doc({**TRIANGLE, "transform": {"scale": 1e15, "translate": [1e15, 0, 0]}}), r"vertex 1.s .* exceed"),
        (doc({**TRIANGLE, "faces": [[0, 1, 2.5]]}), r"meshes\[0\]\.faces: must hold whole numbers"),
        (doc({**TRIANGLE, "vertices": [[0, 0, True], [1, 0, 0], [0, 1, 0]]}), r"vertices: must hold numbers, got"),
        (doc({**TRIANGLE, "file": "a.ply"}), r"meshes\[0\]\.faces: give a file or vertices and faces, not both"),
        (doc({"faces": [[0, 1, 2]]}), r"meshes\[0\]\.vertices: missing"),
        (doc({**TRIANGLE, "normals": [[0, 0, 1]]}), r"meshes\[0\]\.normals: one per vertex"),
        (doc({**TRIANGLE, "color": [2, 0, 0]}), r"meshes\[0\]\.color: each channel must be in \[0, 1\]"),
        (doc({**TRIANGLE, "material": {"ior": 0}}), r"meshes\[0\]\.material\.ior"),
        (doc({**TRIANGLE, "size": 1}), r"meshes\[0\]\.size: unknown field"),
        ({**doc(TRIANGLE), "version": 2}, r"^[^:]*: meshes: unknown field"),
        (doc({"file": "huge.ply"}), r"meshes\[0\]\.file: .*huge\.ply: 300 bytes, over the 100-byte limit"),
    ],
)
def test_bad_meshes_are_one_line_exit_2_and_nothing_written(tmp_path, capsys, monkeypatch, document, message):
    (tmp_path / "huge.ply").write_bytes(b"x" * 300)
    monkeypatch.setattr("raybench.meshes.MAX_MESH_BYTES", 100)
    path = tmp_path / "bad.json"
    path.write_text(document if isinstance(document, str) else json.dumps(document))
    out = tmp_path / "x.png"
    assert run(["render", "--scene", str(path), "--size", "16x8", "-o", str(out)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "Traceback" not in err and not out.exists(), err
    assert __import__("re").search(message, err.removeprefix("raybench: error: ")), err


def test_a_version_3_file_renders_as_its_meshes_placed_by_hand(tmp_path, capsys):
    """`raybench render` of a version-3 file (a box file, turned and moved,
    and an inline triangle) draws what render() draws of the same
    triangles placed here with NumPy; the Renderer traces the same frame
    and a mesh file's camera frames it (no pixel of the background in
    the middle)."""
    box = trimesh.creation.box(extents=(2.0, 1.0, 1.0))
    turned = {"file": box_file(tmp_path), "transform": {"rotate": [0, 30, 0], "translate": [0.5, 0, 6]}}
    behind = {**TRIANGLE, "transform": {"scale": 4, "translate": [-2, -2, 9]}, "color": [0.9, 0.3, 0.1]}
    camera = {"position": [0, 1, 0], "look_at": [0, 0, 6]}
    path = write(tmp_path / "scene.json", doc(turned, behind, camera=camera))
    out = tmp_path / "frame.png"
    assert run(["render", "--scene", path, "--size", "48x32", "--device", "cpu", "-o", str(out)]) == 0
    assert "13 triangles" in capsys.readouterr().out
    c, s = math.cos(math.radians(30)), math.sin(math.radians(30))
    about_y = np.array([[c, 0, s], [0, 1, 0], [-s, 0, c]])
    by_hand = Scene.from_dict(doc(camera=camera)).replaced(
        meshes=[
            SceneMesh(Mesh(np.float32(box.vertices @ about_y.T + [0.5, 0, 6]), np.int32(box.faces))),
            SceneMesh(Mesh(np.float32(np.array(TRIANGLE["vertices"]) * 4 - [2, 2, -9]), np.int32([[0, 1, 2]])),
                      (0.9, 0.3, 0.1)),
        ]
    )  # fmt: skip
    expected = render(by_hand, None, 48, 32, device="cpu")
    assert (np.asarray(Image.open(out).convert("RGB")) == expected.image).all()
    seen = np.unique(expected.hits)
    assert seen[0] == -1 and seen[-1] == 12 and len(seen) > 3  # the background, the inline triangle, the box
    with Renderer(by_hand, 48, 32, device="cpu") as renderer:
        assert (renderer.render().image == expected.image).all()
    obj = tmp_path / "box.obj"
    box.export(obj)
    out = tmp_path / "obj.png"
    assert run(["render", "--scene", str(obj), "--size", "24x24", "--device", "cpu", "-o", str(out)]) == 0
    assert "12 triangles" in capsys.readouterr().out
    middle = np.asarray(Image.open(out).convert("RGB"))[10:14, 10:14]
    assert (middle > 100).all()  # the light grey box, not the dark gradient behind it
    # the file named without --scene (`raybench render model.obj`) is the same frame; both is refused
    plain = tmp_path / "plain.png"
    assert run(["render", str(obj), "--size", "24x24", "--device", "cpu", "-o", str(plain)]) == 0
    assert (np.asarray(Image.open(plain)) == np.asarray(Image.open(out))).all()
    capsys.readouterr()
    assert run(["render", str(obj), "--scene", str(obj), "--size", "24x24", "-o", str(tmp_path / "no.png")]) == 2
    assert "give the scene once" in capsys.readouterr().err
    assert not (tmp_path / "no.png").exists()


def test_the_viewer_counts_a_mesh_scenes_triangles(tmp_path, capsys):
    """The viewer's logic without a window or a trace: a mesh file's scene
    is traced whole (every triangle, + and - step through them), the title
    counts triangles, and --animate, which moves spheres, is refused."""
    from raybench.mesh_render import mesh_scene
    from raybench.viewer.state import ViewerState

    box = trimesh.creation.box()
    scene = mesh_scene(Mesh(np.float32(box.vertices), np.int32(box.faces)))
    state = ViewerState(scene, device="cpu", seed=None, clock=lambda: 0.0)
    request = state.next_request(16, 8)
    assert request.count == 12 and request.scene is scene
    assert "12 triangles" in state.title()
    state.handle_event({"event_type": "key_down", "key": "-", "modifiers": ()})
    assert state.next_request(16, 8).count == 2
    assert state.supply.more() is None and state.supply.more() == "the scene file has 12 triangles, all shown"
    box.export(tmp_path / "box.obj")
    assert run(["view", "--scene", str(tmp_path / "box.obj"), "--animate"]) == 2
    assert capsys.readouterr().err.count("\n") == 1


def test_the_viewer_counts_a_mixed_scenes_primitives(capsys):
    """The viewer's logic without a window or a trace: the example of
    spheres and meshes (--scene mixed) is traced whole, its title counts its
    spheres and triangles together as primitives, and --animate is refused."""
    from raybench import examples
    from raybench.viewer.state import ViewerState

    scene = Scene.load(examples.path("mixed"))
    total = len(scene) + scene.triangles.shape[1]
    assert len(scene) == 3 and scene.traced().kind == "mixed" and len(scene.traced()) == total
    state = ViewerState(scene, device="cpu", seed=None, clock=lambda: 0.0)
    assert state.next_request(16, 8).count == total and f"{total} primitives" in state.title()
    assert run(["view", "--scene", "mixed", "--animate"]) == 2
    assert capsys.readouterr().err.count("\n") == 1
