"""Mesh files in (raybench.meshes): each format trimesh writes reads back as
the same indexed float32 triangles, with the file's vertex normals where it
has them; mesh_leaves lays them out as the triangle primitive's rows; and
each bad file is refused in one line that names the file and the problem.
Debian's assimp test models, where installed, load too."""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import pytest

from raybench import RaybenchError, meshes
from raybench.layout import TRI_A, TRI_B, TRI_C, TRI_NA, TRI_NC, TRI_RED, TRI_SHADED_ROWS, TRI_SMOOTH_ROWS
from raybench.meshes import MESH_COLOUR, Mesh, load_mesh, mesh_leaves

trimesh = pytest.importorskip("trimesh")


def icosphere():
    """A small closed mesh with vertex normals (worked out now: trimesh
    writes the normals it holds)."""
    mesh = trimesh.creation.icosphere(subdivisions=1, radius=2.0)
    assert mesh.vertex_normals.shape == (42, 3)
    return mesh


def refused(path, *words) -> str:
    """load_mesh's error for path: one line naming the file and each word."""
    with pytest.raises(RaybenchError) as caught:
        load_mesh(path)
    message = str(caught.value)
    assert "\n" not in message and str(path) in message, message
    for word in words:
        assert word in message, message
    return message


def same_triangles(mesh: Mesh, source) -> bool:
    """Whether mesh holds source's triangles (as sets of corner points, any
    vertex order or sharing: STL keeps no indices)."""
    got = {tuple(map(tuple, np.round(t, 5))) for t in mesh.vertices[mesh.faces].astype(np.float64)}
    want = {tuple(map(tuple, np.round(t, 5))) for t in np.asarray(source.triangles, np.float64)}
    return got == want


@pytest.mark.parametrize("suffix, normals", [(".obj", True), (".ply", True), (".stl", False), (".glb", True)])
def test_formats_read_back(tmp_path, suffix, normals):
    """OBJ, PLY, STL and GLB written by trimesh read back as the same
    triangles, float32 and int32, with the file's normals (STL has none)."""
    source = icosphere()
    path = tmp_path / f"ico{suffix}"
    if suffix == ".obj":
        path.write_text(trimesh.exchange.obj.export_obj(source, include_normals=True))
    elif suffix == ".ply":
        path.write_bytes(trimesh.exchange.ply.export_ply(source, vertex_normal=True))
    else:
        source.export(path)
    mesh = load_mesh(path)
    assert mesh.vertices.dtype == np.float32 and mesh.faces.dtype == np.int32 and len(mesh) == 80
    assert same_triangles(mesh, source)
    assert (mesh.normals is not None) == normals
    if normals:
        assert mesh.normals.dtype == np.float32 and mesh.normals.shape == mesh.vertices.shape
        # an icosphere's vertex normals point away from its centre
        radial = mesh.vertices / np.linalg.norm(mesh.vertices, axis=1, keepdims=True)
        assert np.allclose(mesh.normals, radial, atol=1e-5)


def test_gltf_with_its_buffers_and_node_transform(tmp_path):
    """A .gltf (JSON beside its binary buffer) read with its node's
    transform applied to the vertices, and to the normals as normals."""
    scene = trimesh.Scene()
    move = np.diag([2.0, 1.0, 1.0, 1.0])
    move[:3, 3] = [10, 0, 0]
    scene.add_geometry(icosphere(), transform=move)
    for name, data in trimesh.exchange.gltf.export_gltf(scene).items():
        (tmp_path / name).write_bytes(data)
    mesh = load_mesh(tmp_path / "model.gltf")
    assert len(mesh) == 80
    assert np.allclose(mesh.vertices.mean(0), [10, 0, 0], atol=1e-5)
    assert np.isclose(mesh.vertices[:, 0].max(), 14, atol=1e-5)
    # an ellipsoid's normal: (x / a^2, y / b^2, z / c^2) about its centre, normalised
    rel = (mesh.vertices - [10, 0, 0]) / [4.0, 4.0, 4.0] * [0.25, 1, 1]
    assert np.allclose(mesh.normals, rel / np.linalg.norm(rel, axis=1, keepdims=True), atol=1e-5)


def test_leaves_rows():
    """mesh_leaves: each face's A, B and C in the TRI_ rows, its colour (the
    default, or the one given), and the corner normals after them only where
    the mesh has normals."""
    vertices = np.float32([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]])
    faces = np.int32([[0, 1, 2], [3, 2, 1]])
    flat = mesh_leaves(Mesh(vertices, faces))
    assert flat.shape == (TRI_SHADED_ROWS, 2) and flat.dtype == np.float32
    assert (flat[TRI_RED : TRI_RED + 3].T == np.float32(MESH_COLOUR)).all()
    assert (mesh_leaves(Mesh(vertices, faces), (0.25, 0.5, 1))[TRI_RED : TRI_RED + 3].T == [0.25, 0.5, 1]).all()
    for row, corner in ((TRI_A, 0), (TRI_B, 1), (TRI_C, 2)):
        assert (flat[row : row + 3].T == vertices[faces[:, corner]]).all()
    normals = np.float32([[0, 0, 1], [0, 1, 0], [1, 0, 0], [0, 0, -1]])
    smooth = mesh_leaves(Mesh(vertices, faces, normals))
    assert smooth.shape == (TRI_SMOOTH_ROWS, 2) and (smooth[:TRI_SHADED_ROWS] == flat).all()
    assert (smooth[TRI_NA : TRI_NA + 3].T == normals[faces[:, 0]]).all()
    assert (smooth[TRI_NC : TRI_NC + 3].T == normals[faces[:, 2]]).all()


def test_degenerate_triangles_load(tmp_path):
    """Triangles of zero area are kept (the triangle's test never hits them)."""
    path = tmp_path / "flat.obj"
    path.write_text("v 0 0 0\nv 1 1 1\nv 2 2 2\nv 0 1 0\nf 1 2 3\nf 1 1 4\nf 1 2 4\n")
    mesh = load_mesh(path)
    assert len(mesh) == 3 and mesh.faces.tolist() == [[0, 1, 2], [0, 0, 3], [0, 1, 3]]


def test_bad_files_each_one_line(tmp_path, monkeypatch):
    """Every bad file: one line naming it and what is wrong."""
    refused(tmp_path / "none.ply", "no such file")
    refused(tmp_path, "not a file")
    (tmp_path / "model.fbx").write_text("x")
    refused(tmp_path / "model.fbx", "unknown mesh format", ".obj")
    whole = trimesh.exchange.ply.export_ply(icosphere())
    (tmp_path / "cut.ply").write_bytes(whole[: len(whole) // 2])
    refused(tmp_path / "cut.ply", "cannot read it as PLY")
    (tmp_path / "cut.gltf").write_text('{"asset": ')
    refused(tmp_path / "cut.gltf", "cannot read it as GLTF", "not JSON")
    (tmp_path / "far.obj").write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 5\n")
    refused(tmp_path / "far.obj", "out of range")
    ply_header = (
        "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\n"
        "element face 1\nproperty list uchar int vertex_indices\nend_header\n0 0 0\n1 0 0\n0 1 0\n"
    )
    (tmp_path / "far.ply").write_text(ply_header + "3 0 1 7\n")
    refused(tmp_path / "far.ply", "face 0", "out of range", "3 vertices")
    (tmp_path / "nan.obj").write_text("v 0 0 0\nv nan 0 0\nv 0 1 0\nf 1 2 3\n")
    refused(tmp_path / "nan.obj", "vertex 1", "non-finite")
    (tmp_path / "inf.ply").write_text(ply_header.replace("1 0 0\n", "inf 0 0\n") + "3 0 1 2\n")
    refused(tmp_path / "inf.ply", "vertex 1", "non-finite")
    (tmp_path / "huge.obj").write_text("v 0 0 0\nv 1e20 0 0\nv 0 1 0\nf 1 2 3\n")
    refused(tmp_path / "huge.obj", "vertex 1", "exceed")
    # trimesh took the first vertex's two coordinates for all: points in a plane (test_fuzz found it)
    (tmp_path / "flat.obj").write_text("v 0 0\nv 0 0 0\nv 1 0 0\nv 0 1 0\nf 2 3 4\n")
    refused(tmp_path / "flat.obj", "x, y and z", ", 2)")
    (tmp_path / "points.obj").write_text("v 0 0 0\nv 1 0 0\n")
    refused(tmp_path / "points.obj", "no faces")
    (tmp_path / "empty.stl").write_bytes(b"")
    refused(tmp_path / "empty.stl")
    (tmp_path / "ok.obj").write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n")
    assert len(load_mesh(tmp_path / "ok.obj")) == 1
    monkeypatch.setattr(meshes, "MAX_MESH_BYTES", 20)
    refused(tmp_path / "ok.obj", "over the 20-byte limit")


# Where Debian's assimp-testmodels package puts its models (CI installs it: .ci/run).
ASSIMP = Path("/usr/share/assimp/models")


def assimp(name: str) -> Path:
    path = ASSIMP / name
    if not path.is_file():
        if os.environ.get("RAYBENCH_REQUIRE_MODELS"):  # CI installs them: there a missing model fails
            pytest.fail(f"RAYBENCH_REQUIRE_MODELS is set and {path} is missing")
        pytest.skip(f"Debian's assimp-testmodels is not installed (no {path})")
    return path


def test_assimp_models_of_each_format():
    """Real models, one a format, against what each file says by other means:
    the Wuson as PLY and as STL (two formats, two parsers) the same
    triangles in the same bounds; the spider OBJ's triangles those its
    `f` lines give (a polygon of n corners being n - 2 triangles); Khronos's
    textured box, a unit cube of 12 triangles, as GLB and as glTF with its
    buffer beside it."""
    ply, stl = load_mesh(assimp("PLY/Wuson.ply")), load_mesh(assimp("STL/Wuson.stl"))
    assert len(ply) == len(stl) > 1000
    assert np.allclose(ply.vertices.min(0), stl.vertices.min(0)) and np.allclose(
        ply.vertices.max(0), stl.vertices.max(0)
    )
    obj = assimp("OBJ/spider.obj")
    corners = [len(line.split()) - 1 for line in obj.read_text(errors="replace").splitlines() if line.startswith("f ")]
    spider = load_mesh(obj)
    assert len(spider) == sum(n - 2 for n in corners) and spider.faces.max() < len(spider.vertices)
    for box in ("glTF2/BoxTextured-glTF-Binary/BoxTextured.glb", "glTF2/BoxTextured-glTF/BoxTextured.gltf"):
        mesh = load_mesh(assimp(box))
        assert len(mesh) == 12 and np.isfinite(mesh.vertices).all()
        assert np.allclose(mesh.vertices.min(0), -0.5) and np.allclose(mesh.vertices.max(0), 0.5)


def test_assimp_bad_models_are_refused_in_one_line():
    """The package's broken glTF files: indices past the vertices, and infinities."""
    refused(assimp("glTF2/IndexOutOfRange/IndexOutOfRange.gltf"), "out of range", "24 vertices")
    refused(assimp("glTF2/BoxWithInfinites-glTF-Binary/BoxWithInfinites.glb"), "non-finite")
