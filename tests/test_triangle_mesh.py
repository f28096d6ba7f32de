"""A painted mesh (meshes.Painted) in place of its scene buffer: the cpu builds the tree of its
primary rays' packets from the mesh's own arrays (kernels/primitives/triangle_mesh.py), and its
leaves are the mesh read through the tree's order: no scene buffer and no leaf buffer. Held to the
scene buffer's path, which the float64 references hold (tests/test_triangle_render.py): the same
trees to the bit, the same pictures and hits."""

from __future__ import annotations

import numpy as np
import pytest
from test_triangle_render import check_against_reference, rays64, reference, thesis_image

from raybench import Camera, RaybenchError, Renderer, Scene, backends
from raybench.bench.meshes import icosphere, random_triangles
from raybench.bvh import WIDE, build
from raybench.kernels.primitives import triangle, triangle_mesh
from raybench.lighting import Light, Shading
from raybench.meshes import Mesh, Painted, mesh_leaves
from raybench.scene_meshes import SceneMesh

W, H = 96, 64
COLOUR = (0.25, 0.5, 0.75)


def camera() -> Camera:
    return Camera(position=(0.3, 0.2, -2.5), look_at=(0.0, 0.0, 0.0), fov_deg=60.0)


def shuffled_icosphere(triangles: int) -> Mesh:
    """An icosphere whose faces are in a random order, so that the tree's order is no
    accident of the file's."""
    mesh = icosphere(triangles)
    order = np.random.default_rng(1).permutation(len(mesh.faces))
    return Mesh(mesh.vertices, np.ascontiguousarray(mesh.faces[order]), None)


@pytest.mark.parametrize("kind", ["icosphere", "random"])
@pytest.mark.parametrize("many", [False, True], ids=["one thread's way", "every thread's way"])
def test_the_tree_of_the_mesh_is_the_scene_buffers_to_the_bit(kind, many, monkeypatch):
    monkeypatch.setattr(triangle_mesh, "INDEXED_FROM", 0)  # a small mesh read through the order too
    n = 5120 if many else 320
    assert (n > WIDE) == many
    mesh = shuffled_icosphere(n) if kind == "icosphere" else random_triangles(n)
    shared = len(mesh.vertices) < 2 * n
    assert shared == (kind == "icosphere")
    cost = triangle.PACKETS_NODE_COST
    ours = build((mesh.vertices, mesh.faces), threads=2, primitive=triangle_mesh, node_cost=cost)
    theirs = build(mesh_leaves(mesh), threads=2, primitive=triangle, node_cost=cost)
    assert ours.nodes.tobytes() == theirs.nodes.tobytes() and ours.depth == theirs.depth
    assert np.array_equal(ours.order, theirs.order)
    if shared:  # no leaf buffer
        # the leaves are the mesh itself, read through the tree's order, and what they read is
        # the scene buffer's leaf buffer to the bit
        vertices, faces, order = ours.ordered
        assert vertices is mesh.vertices and faces is mesh.faces and order is ours.order
        assert np.array_equal(vertices[faces[order]].reshape(n, 9).T, theirs.ordered)
    else:  # each triangle its own vertices: copied, as the scene buffer's
        assert ours.ordered.flags.f_contiguous and ours.ordered.tobytes("A") == theirs.ordered.tobytes("A")
        k = int(ours.order[7])
        assert ours.ordered[:, 7].tolist() == mesh.vertices[mesh.faces[k]].ravel().tolist()


def test_a_large_mesh_that_shares_its_vertices_is_read_through_the_trees_order():
    """The rule (triangle_mesh.read_through): shared vertices and at least INDEXED_FROM triangles;
    the arrays' sizes alone count, so views of one row stand in for a large mesh."""
    n = triangle_mesh.INDEXED_FROM
    rows = np.zeros((1, 3), np.float32), np.zeros((1, 3), np.int32)
    large = [np.broadcast_to(a, (m, 3)) for a, m in zip(rows, (n // 2, n))]
    assert triangle_mesh.read_through(large)
    assert not triangle_mesh.read_through((large[0][: n - 1], large[1][: n - 1]))  # fewer triangles
    assert not triangle_mesh.read_through((np.broadcast_to(rows[0], (3 * n, 3)), large[1]))  # their own vertices
    small = icosphere(1280)
    assert not triangle_mesh.read_through((small.vertices, small.faces))


@pytest.mark.parametrize("kind", ["icosphere", "random"])
@pytest.mark.parametrize("tree_width", [4, 2])
def test_a_painted_meshs_frames_are_its_scene_buffers(tree_width, kind, monkeypatch):
    monkeypatch.setattr(triangle_mesh, "INDEXED_FROM", 0)
    mesh = shuffled_icosphere(5120) if kind == "icosphere" else random_triangles(3000)
    basis = camera().basis(W, H)
    options = {"tree_width": tree_width}
    with (
        backends.tracer("cpu", Painted(mesh, COLOUR), W, H, primitive="triangle", **options) as ours,
        backends.tracer("cpu", mesh_leaves(mesh, COLOUR), W, H, primitive="triangle", **options) as theirs,
    ):
        if tree_width == 4:  # the packets read the mesh itself: no scene buffer held
            assert ours.spheres is None and ours.shaded.shape == (triangle.LEAF_ROWS, 1)
            # shared vertices read through the tree's order, a triangle's own copied
            assert isinstance(ours.bvh.ordered, tuple) == (kind == "icosphere")
        else:  # the binary tree's walk reads the scene buffer, made from the mesh
            assert ours.spheres.shape == theirs.spheres.shape
        for count in (None, 1000):  # the whole mesh, then a frame of its first triangles (their own tree)
            image, hits = (a.copy() for a in ours.trace(basis, count))
            want_image, want_hits = theirs.trace(basis, count)
            assert (hits >= 0).mean() > 0.05
            assert np.array_equal(hits, want_hits) and np.array_equal(image, want_image)


def test_a_painted_meshs_whitted_frame_is_its_scene_buffers():
    """Whitted's rays read the scene buffer: the tracer makes it from the painted mesh."""
    mesh = shuffled_icosphere(1280)
    scene = Scene([], [], [], meshes=[SceneMesh(mesh, COLOUR)])
    scene = scene.with_lights([Light((2.0, 3.0, -3.0), (1.0, 1.0, 1.0))])
    shading = Shading.of(scene.traced())
    basis = camera().basis(W, H)
    with (
        backends.tracer("cpu", Painted(mesh, COLOUR), W, H, shading=shading, primitive="triangle") as ours,
        backends.tracer("cpu", mesh_leaves(mesh, COLOUR), W, H, shading=shading, primitive="triangle") as theirs,
    ):
        image, hits = (a.copy() for a in ours.trace(basis))
        want_image, want_hits = theirs.trace(basis)
        assert np.array_equal(hits, want_hits) and np.array_equal(image, want_image)
        assert ours.ray_counts.tolist() == theirs.ray_counts.tolist() and ours.ray_counts[1] > 0


def test_a_scene_of_one_mesh_renders_on_the_cpu_without_its_buffer():
    """Scene.traced gives a scene of one mesh as the mesh itself; the Renderer's cpu frame is the
    float64 reference's, and the scene never made its merged buffer."""
    mesh = shuffled_icosphere(1280)
    scene = Scene([], [], [], camera=camera(), meshes=[SceneMesh(mesh, COLOUR)])
    traced = scene.traced()
    assert isinstance(traced.leaves, Painted) and len(traced) == 1280
    with Renderer(scene, W, H, device="cpu") as renderer:
        frame = renderer.render()
    assert "triangles" not in vars(scene)  # the cached property never asked for
    leaves = mesh_leaves(mesh, COLOUR)
    origin, dirs = rays64(scene.camera, W, H)
    index, _t, normal, margin = reference(leaves, origin, dirs)
    assert 0.2 < (frame.hits >= 0).mean() < 0.9
    check_against_reference(frame, leaves, index, margin, thesis_image(leaves, index, normal, dirs, W, H))
    assert np.array_equal(traced.buffer(), scene.triangles)


def test_a_painted_mesh_is_refused_as_another_kind_in_one_line():
    with pytest.raises(RaybenchError, match="traced as primitive 'triangle'"):
        backends.tracer("cpu", Painted(random_triangles(10)), W, H, primitive="mixed")
