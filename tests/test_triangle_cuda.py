"""Triangle meshes on cuda: under numba's simulator where there is no GPU
(tiny frames, a few hundred triangles: every simulated thread is a Python
thread), for real on the GPU machine. Held to test_triangle_render's float64
renderer (Moller-Trumbore over every triangle), as the cpu's frames are:
the thesis's shading, Whitted's default light with flat and smooth normals;
trees from the host's SAH builder and from the GPU's (each of its
qualities), a valid tree in the one layout; the packet walk, brute force,
and Whitted's pixel program and wavefront one frame; mirrors and glass
(the wavefront against the pixel program; on a GPU against the cpu too);
`raybench render --scene FILE.ply --device cuda`; and what is refused."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest
import trimesh
from PIL import Image
from test_triangle_render import check_against_reference, cli, mesh_of, rays64, reference, thesis_image

from raybench import RaybenchError, Scene, SceneMesh, backends, layout
from raybench.backends import cuda as cuda_backend
from raybench.lighting import DEFAULT_AMBIENT, Material, Shading
from raybench.mesh_render import mesh_scene, recoloured, render_mesh
from raybench.meshes import Mesh

SIM = cuda_backend.simulated()
pytestmark = [
    pytest.mark.gpu,
    pytest.mark.skipif(not cuda_backend.available(), reason="no CUDA GPU and the simulator is off"),
]

# The simulator runs every GPU thread as Python: keep its frames tiny.
W, H = (24, 16) if SIM else (160, 120)
# The packet walk votes at a barrier, each a wait of every simulated thread.
PACKET_SIZE = (16, 8) if SIM else (W, H)
# The icosphere's subdivisions: 80 triangles in the simulator, where the GPU
# build's every thread is a Python thread too; 1,280 on a GPU.
SUBDIVISIONS = 1 if SIM else 3


def icosphere(normals: bool = False) -> Mesh:
    """An icosphere, with its vertex normals (its vertices' directions) where asked."""
    shape = trimesh.creation.icosphere(subdivisions=SUBDIVISIONS)
    vertices = np.asarray(shape.vertices, np.float32)
    given = vertices / np.linalg.norm(vertices, axis=1, keepdims=True) if normals else None
    return Mesh(vertices, np.asarray(shape.faces, np.int32), given)


def frames_alike(a, b) -> None:
    """Two cuda frames of one scene by two ways (a tree from another
    builder, another walk): each primitive's test is the same arithmetic
    whichever way reached it, and ties go to the smaller index, so the
    same hits and bytes; on a GPU, whose compiler may fuse another kernel's
    multiply-adds otherwise, but where rounding decides (a ray through an
    edge), and within a step."""
    if SIM:
        assert np.array_equal(a.hits, b.hits) and np.array_equal(a.image, b.image)
    else:
        assert (a.hits != b.hits).mean() <= 0.005
        assert (np.abs(a.image.astype(int) - b.image.astype(int)).max(axis=2) <= 1).mean() >= 0.995


def check_tree(tree, leaves) -> None:
    """A tree over triangles in raybench.bvh's layout: every triangle in one
    leaf, the leaf buffer the scene's vertices in its order, each box inside
    its parent's and around its triangles' vertices."""
    n = leaves.shape[1]
    assert sorted(tree.order.tolist()) == list(range(n))
    assert np.array_equal(tree.ordered, leaves[: layout.TRI_ROWS, tree.order])
    seen = np.zeros(n, int)
    todo = [(0, None)]
    while todo:
        row, outer = todo.pop()
        for slot in range(2):
            box = tree.nodes[row, 6 * slot : 6 * slot + 6]
            ref, count = tree.links[row, layout.REF + slot], tree.links[row, layout.COUNT + slot]
            if count == 0:
                continue
            if outer is not None:
                assert (box[:3] >= outer[:3]).all() and (box[3:] <= outer[3:]).all()
            if count == layout.INNER:
                todo.append((ref, box))
                continue
            for j in range(ref, ref + count):
                corners = leaves[: layout.TRI_ROWS, tree.order[j]].reshape(3, 3)
                assert (box[:3] <= corners.min(axis=0)).all() and (box[3:] >= corners.max(axis=0)).all()
                seen[tree.order[j]] += 1
    assert (seen == 1).all()


@pytest.fixture(scope="module")
def ball():
    """The icosphere seen from the camera fitted to it, and the reference's answer."""
    scene = mesh_scene(icosphere())
    origin, dirs = rays64(scene.camera, W, H)
    index, t, normal, margin = reference(scene.triangles, origin, dirs)
    return scene, origin, dirs, index, t, normal, margin


@pytest.mark.slow
def test_thesis_frames_are_the_float64_reference_on_every_tree(ball):
    """The host's SAH tree and the GPU builder's trees (each quality): the
    reference's hits and colours, one frame, and valid trees."""
    scene, _origin, dirs, index, _t, normal, margin = ball
    host = render_mesh(scene, W, H, device="cuda", walk="ray")
    assert host.device == "cuda" and 0.2 < (host.hits >= 0).mean() < 0.9
    check_against_reference(
        host, scene.triangles, index, margin, thesis_image(scene.triangles, index, normal, dirs, W, H)
    )
    for quality in ("sah", "lbvh", "treelet"):
        with backends.tracer("cuda", scene.triangles, W, H, primitive="triangle", build="gpu", quality=quality,
                             walk="ray") as tracer:  # fmt: skip
            image, hits = tracer.trace(scene.camera.basis(W, H))
            assert tracer.bvh.built_on == "gpu", quality
            check_tree(tracer.bvh.to_host(), scene.triangles)
            frames_alike(SimpleNamespace(image=image, hits=hits), host)


def test_packet_walk_and_brute_force_give_the_ray_walks_frame(ball):
    """The block's rays walking as one packet, and the simple kernel's scan
    of every triangle: the ray walk's frame."""
    scene = ball[0]
    width, height = PACKET_SIZE
    ray = render_mesh(scene, width, height, device="cuda", walk="ray")
    frames_alike(render_mesh(scene, width, height, device="cuda", walk="packet"), ray)
    frames_alike(render_mesh(scene, width, height, device="cuda", accel="none", kernel="simple"), ray)


def test_a_mesh_of_one_colour_keeps_its_colour_once(ball):
    """In the tree's order on cuda, a mesh whose triangles share one colour
    keeps its vertices' rows and that colour once, in the columns after its
    last triangle (a quarter of the buffer's bytes less); one of two colours
    keeps every triangle's own. Both are the float64 reference's pictures,
    each in its own colours."""
    scene, _origin, dirs, index, _t, normal, margin = ball
    n = scene.triangles.shape[1]
    two = scene.triangles.copy()
    two[layout.TRI_RED, ::2] = 0.25  # every other triangle less red
    one = (layout.TRI_ROWS, -(-(n + 1) // 32) * 32)  # the colour's columns after the triangles, to 128 bytes a row
    for leaves, kept in ((scene.triangles, one), (two, (layout.TRI_SHADED_ROWS, n))):
        with backends.tracer("cuda", leaves, W, H, primitive="triangle", walk="ray") as tracer:
            image, hits = tracer.trace(scene.camera.basis(W, H))
            assert tracer.d_spheres.shape == kept
            frame = SimpleNamespace(image=image.copy(), hits=hits.copy())
        check_against_reference(frame, leaves, index, margin, thesis_image(leaves, index, normal, dirs, W, H))


def lambert(scene, origin, dirs, index, t, normal, plane):
    """Whitted's picture of a convex mesh under its one default light, in
    float64 (test_triangle_render's): colour times (ambient + max(n.L, 0)),
    n (the shading normal) turned to the viewer; no shadow falls on a convex
    mesh's faces that face the light (plane: their normals), and every
    other face is in the shadow of the mesh, whatever its smooth normal says."""
    point = origin + np.where(index >= 0, t, 0)[:, None] * dirs
    to_light = np.asarray(scene.lights[0].position) - point
    to_light /= np.linalg.norm(to_light, axis=1, keepdims=True)
    towards = -np.sign(np.einsum("rk,rk->r", plane, dirs))[:, None]
    facing = np.maximum(np.einsum("rk,rk->r", normal * towards, to_light), 0)
    facing *= np.einsum("rk,rk->r", plane * towards, to_light) > 0
    colour = scene.triangles[layout.TRI_RED : layout.TRI_RED + 3, np.maximum(index, 0)].T.astype(np.float64)
    lit = colour * (np.asarray(DEFAULT_AMBIENT) + facing[:, None])
    xs, ys = np.meshgrid(np.arange(W), np.arange(H))
    miss = np.stack([xs.ravel() / 1024, ys.ravel() / 1024, xs.ravel() / 786], axis=1)
    return np.floor(np.clip(np.where((index >= 0)[:, None], lit, miss), 0, 1) * 255 + 0.5).astype(int).reshape(H, W, 3)


def smooth_normals(leaves, index, point):
    """The corners' normals of each ray's nearest triangle blended by the
    hit point's barycentric weights, in float64, unit length."""
    corners = leaves[: layout.TRI_ROWS, np.maximum(index, 0)].T.astype(np.float64).reshape(-1, 3, 3)
    a, b, c = corners[:, 0], corners[:, 1], corners[:, 2]
    whole = np.cross(b - a, c - a)
    area = np.einsum("rk,rk->r", whole, whole)
    wa = np.einsum("rk,rk->r", np.cross(c - b, point - b), whole) / area
    wb = np.einsum("rk,rk->r", np.cross(a - c, point - c), whole) / area
    normals = leaves[layout.TRI_NA :, np.maximum(index, 0)].T.astype(np.float64).reshape(-1, 3, 3)
    blend = wa[:, None] * normals[:, 0] + wb[:, None] * normals[:, 1] + (1 - wa - wb)[:, None] * normals[:, 2]
    return blend / np.linalg.norm(blend, axis=1, keepdims=True)


@pytest.mark.slow
@pytest.mark.parametrize("smooth", [False, True])
def test_whitted_frames_are_the_float64_reference(ball, smooth):
    """Whitted shading under the mesh's default light, flat and with the
    corners' normals (an icosphere's own: its vertices' directions): the
    wavefront (its walks read the triangles from its packed copy) and the
    pixel program, each the reference's, one frame."""
    scene, origin, dirs, index, t, plane, margin = ball
    normal = plane
    if smooth:
        scene = mesh_scene(icosphere(normals=True))
        assert scene.triangles.shape[0] == layout.TRI_SMOOTH_ROWS
        normal = smooth_normals(scene.triangles, index, origin + np.where(index >= 0, t, 0)[:, None] * dirs)
    scene = recoloured(scene, (0.9, 0.6, 0.3))
    expected = lambert(scene, origin, dirs, index, t, normal, plane)
    # depth 1: a matte mesh casts no bounce, and each wave is launches the simulator pays for
    wave = render_mesh(scene, W, H, device="cuda", shading="whitted", depth=1)
    pixel = render_mesh(scene, W, H, device="cuda", shading="whitted", depth=1, schedule="pixel")
    for frame in (wave, pixel):
        check_against_reference(frame, scene.triangles, index, margin, expected)
    if SIM:  # the wavefront sums its light in fixed point, the pixel program in floats: a step apart at most
        assert np.array_equal(wave.hits, pixel.hits) and wave.rays == pixel.rays
        assert np.abs(wave.image.astype(int) - pixel.image.astype(int)).max() <= 1
    assert wave.rays["shadow"] > 0 and wave.rays["reflection"] == 0


def glass_and_mirror() -> Scene:
    """A glass icosphere over a mirror floor (two triangles), lit by the
    mesh's default light: reflection and refraction rays, exact Fresnel."""
    ball = icosphere()
    floor = Mesh(
        np.float32([[-3, -1.2, -3], [3, -1.2, -3], [3, -1.2, 3], [-3, -1.2, 3]]), np.int32([[0, 2, 1], [0, 3, 2]])
    )
    vertices = np.concatenate([ball.vertices, floor.vertices])
    faces = np.concatenate([ball.faces, floor.faces + len(ball.vertices)])
    # the camera and light fitted to both; then each its own material, the ball's triangles first
    scene = mesh_scene(Mesh(vertices, faces.astype(np.int32)))
    glass = Material(specular=0.5, reflect=0.1, transmit=0.8, ior=1.5)
    mirror = Material(reflect=0.8)
    return scene.replaced(meshes=[SceneMesh(ball, material=glass), SceneMesh(floor, material=mirror)])


@pytest.mark.slow
def test_glass_and_mirrors_the_wavefront_is_the_pixel_program():
    """Mirrors and glass of triangles: the wavefront's frame (its walks read
    the triangles from its packed copy) is the pixel program's, within a
    step where the fixed-point sums round the other way; on a GPU, the
    cpu's frame too, within a step on 99.5% of the pixels."""
    scene = glass_and_mirror()
    shading = Shading.of(scene, 2, 1)
    basis = scene.camera.basis(W, H)

    def frame(device, **options):
        with backends.tracer(device, scene.triangles, W, H, shading, primitive="triangle", **options) as tracer:
            image, hits = tracer.trace(basis)
            return image.copy(), hits.copy(), tracer.ray_counts.copy()

    wave = frame("cuda", build="gpu")
    pixel = frame("cuda", schedule="pixel")
    assert wave[2][2] > 0 and wave[2][3] > 0  # reflection and refraction rays
    steps = np.abs(wave[0].astype(int) - pixel[0].astype(int)).max(axis=2)
    if SIM:
        assert np.array_equal(wave[1], pixel[1]) and np.array_equal(wave[2], pixel[2])
        assert steps.max() <= 1 and (steps > 0).mean() <= 0.01
    else:
        # the cpu's triangle kernels compile for minutes on CI's 2 cores: on the GPU machine alone
        cpu = frame("cpu", threads=4)
        for image, hits, _rays in (wave, pixel):
            assert (np.abs(image.astype(int) - cpu[0].astype(int)).max(axis=2) <= 1).mean() >= 0.995
            assert (hits == cpu[1]).mean() >= 0.995
        assert (steps > 1).mean() <= 0.01


def test_render_a_ply_file_on_cuda(capsys, tmp_path):
    """raybench render --scene FILE.ply --device cuda: a PNG of the mesh,
    render_mesh's frame on cuda, the same as the float64 reference's."""
    path = tmp_path / "ball.ply"
    trimesh.creation.icosphere(subdivisions=1).export(path)
    out = tmp_path / "ball.png"
    code, stdout, err = cli(capsys, "render", "--scene", path, "--size", f"{W}x{H}", "--device", "cuda", "-o", out)
    assert code == 0, err
    assert "80 triangles" in stdout and "cuda" in stdout
    from raybench.meshes import load_mesh

    scene = mesh_scene(load_mesh(path))
    image = np.asarray(Image.open(out).convert("RGB"))
    assert (image == render_mesh(scene, W, H, device="cuda").image).all()
    origin, dirs = rays64(scene.camera, W, H)
    index, _t, normal, _margin = reference(scene.triangles, origin, dirs)
    close = (np.abs(image.astype(int) - thesis_image(scene.triangles, index, normal, dirs, W, H)) <= 1).all(axis=2)
    assert close.mean() >= 0.995


def test_what_cuda_refuses_of_a_mesh_is_one_line(monkeypatch):
    """The fast kernel (the sphere's cull), moving a mesh, and a mesh larger
    than the GPU's free memory."""
    leaves = mesh_scene(mesh_of(trimesh.creation.box())).triangles
    with pytest.raises(RaybenchError, match="kernel 'fast'"):
        backends.tracer("cuda", leaves, W, H, primitive="triangle", accel="none", kernel="fast")
    with backends.tracer("cuda", leaves, W, H, primitive="triangle", accel="none", kernel="simple") as tracer:
        with pytest.raises(RaybenchError, match="traced as it was given"):
            tracer.update(leaves)

    from raybench.backends.cuda import tracer as cuda_tracer

    class Small:
        """A context with 1 MiB free: a mesh of 100,000 triangles does not fit."""

        @staticmethod
        def get_memory_info():
            return 2**20, 2**30

    monkeypatch.setattr(cuda_tracer.cuda, "current_context", lambda: Small)
    many = np.ascontiguousarray(np.repeat(leaves, 100_000 // leaves.shape[1] + 1, axis=1)[:, :100_000])
    for options in ({}, {"build": "gpu"}, {"accel": "none", "kernel": "simple"}):
        with pytest.raises(RaybenchError, match=r"^bvh: 100,000 triangles need .* on the cuda GPU") as error:
            backends.tracer("cuda", many, W, H, primitive="triangle", **options)
        assert "\n" not in str(error.value)


def test_the_spheres_kernels_are_the_modules_own():
    """A sphere scene launches the modules' own kernels, the source and the
    compiled code they had before triangles; a mesh's are copies, compiled
    from the same source over the triangle's answers (compiled.rebound)."""
    from raybench.backends.cuda import build, kinds, program, wavefront
    from raybench.kernels.primitives import triangle

    spheres, triangles = kinds.programs("sphere"), kinds.programs("triangle")
    assert spheres.program is program and spheres.wavefront is wavefront
    assert spheres.build.bounds_up is build._bounds_up and spheres.stages.extend is wavefront._extend
    assert triangles.primitive is triangle and triangles.build.primitive is triangle
    for name in ("_bvh_kernel", "_bvh_packet_kernel", "_whitted_kernel", "_render_kernel"):
        mine, theirs = getattr(triangles.program, name), getattr(program, name)
        assert mine is not theirs and source(mine).__code__ is source(theirs).__code__
    assert source(triangles.stages.extend).__code__ is source(wavefront._extend).__code__
    # the copies' globals hold the triangle's program, the modules' the sphere's
    assert triangles.program._render_pixel_bvh is triangles.program._made(triangle).render_pixel_bvh
    assert program._render_pixel_bvh is program._made().render_pixel_bvh
    assert triangles.program._render_pixel_bvh is not program._render_pixel_bvh


def source(kernel):
    """The Python a numba-cuda kernel (or the simulator's stand-in) was made from."""
    return getattr(kernel, "py_func", None) or kernel.fn
