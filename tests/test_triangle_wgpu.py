"""Triangle meshes traced on wgpu (triangle.wgsl in the shader in sphere.wgsl's
place), held to the float64 renderer that test_triangle_render.py holds the
cpu's frames to: Moller-Trumbore over every triangle, the thesis's colour -
(1 - cos), Whitted's one default light on a convex mesh, and here smooth
normals blended by the hit's barycentrics. The tree built on the host and on
the GPU (triangle_build.wgsl), brute force, the packet walk where the adapter
has subgroups, Whitted by pixel and by wavefront: one frame, to the byte, on
a CPU adapter. Mirrors and glass are shared code (whitted.wgsl), held to the
cpu on spheres; here every way of tracing them gives one frame. The cpu's
own triangle frames are not traced here: its kernels for a kind compile at a
process's first mesh frame (backends/cpu/kinds.py), minutes on CI's cores,
where the reference takes a second.

These tests skip where wgpu finds no adapter at all, except where
RAYBENCH_REQUIRE_WGPU=1 (CI sets it): there that is a failure.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
import test_triangle_render as cpu_tests
from test_triangle_render import H, W, box, icosphere, rays64, reference, to_bytes

from raybench import Camera, RaybenchError, SceneMesh, backends, bvh, layout
from raybench.backends.wgpu import adapters, compute
from raybench.backends.wgpu import build as gpu_build
from raybench.kernels.primitives import triangle
from raybench.layout import TRI_NA, TRI_RED, TRI_ROWS, TRI_SMOOTH_ROWS
from raybench.lighting import DEFAULT_AMBIENT, Material
from raybench.mesh_render import mesh_scene, recoloured, render_mesh
from raybench.meshes import Mesh

pytestmark = pytest.mark.gpu


def wgpu(scene, adapter, **options):
    return render_mesh(scene, W, H, device="wgpu", adapter=adapter, **options)


def same(frames, adapter):
    """Every frame the first's hits, bytes and rays cast, on a CPU adapter
    (it rounds every operation alike wherever it is compiled); on a GPU,
    whose compiler may fuse a product into a sum in one function and not in
    another, which tips a ray on an edge, the hits on 99.5% of the pixels,
    the colours within a step there, and the rays within 1%."""
    first = frames[0]
    exact = adapters.choose(adapter).type == "CPU"
    for other in frames[1:]:
        hits = other.hits == first.hits
        close = (np.abs(other.image.astype(int) - first.image.astype(int)) <= (0 if exact else 1)).all(axis=2)
        assert (hits.all() and close.all()) if exact else (hits.mean() >= 0.995 and close.mean() >= 0.995)
        for kind, count in (first.rays or {}).items():
            assert other.rays[kind] == count if exact else abs(other.rays[kind] - count) <= 0.01 * count


# the cpu tests' meshes and their float64 answers, one fixture for both files (pytest finds it by this name)
outside = cpu_tests.outside


def test_thesis_frames_are_the_float64_reference(adapter, outside):
    """The tree built on the host and on the GPU, brute force, and the packet
    walk where there are subgroups: the reference's hits and colours, and
    one frame."""
    scene, dirs, index, normal, margin = outside
    frames = [wgpu(scene, adapter), wgpu(scene, adapter, build="gpu"), wgpu(scene, adapter, accel="none")]
    if compute.PACKET_FEATURE in adapters.choose(adapter).adapter.features:
        frames.append(wgpu(scene, adapter, walk="packet"))
    assert frames[0].device == "wgpu" and 0.2 < (frames[0].hits >= 0).mean() < 0.9
    expected = cpu_tests.thesis_image(scene.triangles, index, normal, dirs)
    cpu_tests.check_against_reference(frames[0], scene.triangles, index, margin, expected)
    same(frames, adapter)


@pytest.mark.parametrize("quality", gpu_build.QUALITIES)
def test_gpu_tree_over_triangles_is_valid(adapter, quality):
    """The GPU's tree over a mesh (triangle_build.wgsl: three half sizes a
    triangle): every triangle in one leaf, its vertices in the leaf buffer in
    leaf order, each leaf's box around its triangles' padded boxes (the
    Python's extent), each child's inside its parent's."""
    import wgpu

    leaves = mesh_scene(box()).triangles
    leaves = np.ascontiguousarray(np.concatenate([leaves, mesh_scene(icosphere()).triangles], axis=1))
    n = leaves.shape[1]
    device = adapters.request_device(adapters.choose(adapter))
    rows = device.create_buffer_with_data(data=compute.triangle_rows(leaves).tobytes(), usage=wgpu.BufferUsage.STORAGE)
    kernels = gpu_build.Kernels(device, "triangle")
    builder = gpu_build.Builder(device, rows, n, quality=quality, kernels=kernels)
    tree = builder.to_host(builder.run(builder.encode_build).depth)
    assert sorted(tree.order.tolist()) == list(range(n))
    assert np.array_equal(tree.ordered, leaves[:TRI_ROWS, tree.order])
    extent = triangle.make(lambda f: f).extent
    seen = np.zeros(n, int)
    todo = [(0, None)]
    while todo:
        row, outer = todo.pop()
        for slot in range(2):
            lo, hi = tree.nodes[row, 6 * slot : 6 * slot + 3], tree.nodes[row, 6 * slot + 3 : 6 * slot + 6]
            ref, count = tree.links[row, layout.REF + slot], tree.links[row, layout.COUNT + slot]
            if outer is not None:
                assert (lo >= outer[0]).all() and (hi <= outer[1]).all()
            if count == layout.INNER:
                todo.append((ref, (lo, hi)))
                continue
            assert 0 < count <= bvh.LEAF_MAX
            for k in tree.order[ref : ref + count]:
                seen[k] += 1
                cx, cy, cz, hx, hy, hz = extent(leaves, k)
                assert (lo <= np.float32([cx - hx, cy - hy, cz - hz])).all()
                assert (hi >= np.float32([cx + hx, cy + hy, cz + hz])).all()
    assert (seen == 1).all()


def test_no_ray_slips_through_a_closed_mesh(adapter):
    """Watertight: from inside the icosphere every ray hits it, through
    either tree."""
    camera = Camera((0.01, 0.02, -0.03), (0.3, 0.2, 1.0), fov_deg=100.0)
    scene = mesh_scene(icosphere()).replaced(camera=camera)
    for build in ("host", "gpu"):
        frame = wgpu(scene, adapter, build=build)
        assert (frame.hits >= 0).all(), (build, (frame.hits < 0).sum())


def lit_image(scene, normal, index, t, origin, dirs):
    """Whitted's picture of a convex mesh under its one light in float64:
    colour times (ambient + max(n.L, 0)), n turned to the viewer; the
    gradient where a ray hits nothing."""
    point = origin + np.where(index >= 0, t, 0)[:, None] * dirs  # misses at the origin: unused, and finite
    to_light = np.asarray(scene.lights[0].position) - point
    facing = np.maximum(np.einsum("rk,rk->r", normal, to_light / np.linalg.norm(to_light, axis=1, keepdims=True)), 0)
    colour = scene.triangles[TRI_RED : TRI_RED + 3, np.maximum(index, 0)].T.astype(np.float64)
    lit = colour * (np.asarray(DEFAULT_AMBIENT) + facing[:, None])
    xs, ys = np.meshgrid(np.arange(W), np.arange(H))
    miss = np.stack([xs.ravel() / 1024, ys.ravel() / 1024, xs.ravel() / 786], axis=1)
    return to_bytes(np.where((index >= 0)[:, None], lit, miss)).reshape(H, W, 3)


def facing_viewer(n, dirs):
    return n * -np.sign(np.einsum("rk,rk->r", n, dirs))[:, None]


def test_whitted_frames_are_the_float64_reference(adapter):
    """Whitted shading of a convex mesh under its default light (ambient plus
    Lambert, no shadow on its own lit faces): by pixel through either tree,
    and by wavefront, one frame, the reference's."""
    scene = recoloured(mesh_scene(icosphere()), (0.9, 0.6, 0.3))
    origin, dirs = rays64(scene.camera)
    index, t, normal, margin = reference(scene.triangles, origin, dirs)
    expected = lit_image(scene, facing_viewer(normal, dirs), index, t, origin, dirs)
    frames = [
        wgpu(scene, adapter, shading="whitted"),
        wgpu(scene, adapter, shading="whitted", build="gpu"),
        wgpu(scene, adapter, shading="whitted", schedule="wavefront"),
    ]
    cpu_tests.check_against_reference(frames[0], scene.triangles, index, margin, expected)
    same(frames, adapter)
    assert frames[0].rays["shadow"] > 0 and frames[0].rays["reflection"] == 0


def with_normals(mesh: Mesh) -> Mesh:
    """The icosphere (centred on the origin) with its vertex normals: each vertex's direction."""
    v = mesh.vertices.astype(np.float64)
    return Mesh(mesh.vertices, mesh.faces, (v / np.linalg.norm(v, axis=1, keepdims=True)).astype(np.float32))


def blended(leaves, index, t, origin, dirs):
    """The corners' normals blended by each hit's barycentrics, in float64,
    turned to the viewer (the plane's side)."""
    k = np.maximum(index, 0)
    a, b, c = (leaves[3 * j : 3 * j + 3, k].T.astype(np.float64) for j in range(3))
    p = origin + np.where(index >= 0, t, 0)[:, None] * dirs
    plane = np.cross(b - a, c - a)
    area = np.einsum("rk,rk->r", plane, plane)
    weights = [np.einsum("rk,rk->r", np.cross(q - p, r - p), plane) / area for q, r in ((b, c), (c, a), (a, b))]
    n = sum(w[:, None] * leaves[TRI_NA + 3 * j : TRI_NA + 3 * j + 3, k].T for j, w in enumerate(weights))
    n /= np.linalg.norm(n, axis=1, keepdims=True)
    return facing_viewer(n, dirs)


def test_smooth_normals_shade_by_their_blend(adapter):
    """A mesh with vertex normals: Whitted's light falls by the corners'
    normals blended at each hit (the reference's), not by the plane's."""
    scene = recoloured(mesh_scene(with_normals(icosphere())), (0.9, 0.6, 0.3))
    assert scene.triangles.shape[0] == TRI_SMOOTH_ROWS
    origin, dirs = rays64(scene.camera)
    index, t, _normal, margin = reference(scene.triangles, origin, dirs)
    expected = lit_image(scene, blended(scene.triangles, index, t, origin, dirs), index, t, origin, dirs)
    frame = wgpu(scene, adapter, shading="whitted")
    cpu_tests.check_against_reference(frame, scene.triangles, index, margin, expected)
    without = scene.replaced(
        meshes=[dataclasses.replace(m, mesh=Mesh(m.mesh.vertices, m.mesh.faces)) for m in scene.meshes]
    )
    assert without.triangles.shape[0] == TRI_NA  # the colour rows, then no normals
    flat = wgpu(without, adapter, shading="whitted")
    assert (np.abs(flat.image.astype(int) - frame.image.astype(int)).max(axis=2) > 2).mean() > 0.05


def test_mirrors_and_glass_trace_alike_every_way(adapter):
    """Glass (exact Fresnel) in front of a mirror floor, an area light's
    shadows: reflected and refracted rays cast, and by pixel through either
    tree, by wavefront and by brute force, one frame and one count of rays."""
    parts = [icosphere(), box()]
    parts[1] = Mesh(parts[1].vertices * np.float32([3, 0.2, 3]) - np.float32([0, 1.2, 0]), parts[1].faces)
    mesh = Mesh(
        np.concatenate([p.vertices for p in parts]),
        np.concatenate([parts[0].faces, parts[1].faces + len(parts[0].vertices)]).astype(np.int32),
    )
    # the camera and light fitted to both; then each part its own material, the glass's triangles first
    scene = mesh_scene(mesh).replaced(
        meshes=[
            SceneMesh(parts[0], material=Material(transmit=0.8, reflect=0.1, specular=0.5)),
            SceneMesh(parts[1], material=Material(reflect=0.5)),
        ]
    )
    options = [{}, {"build": "gpu"}, {"schedule": "wavefront"}, {"accel": "none"}]
    frames = [wgpu(scene, adapter, shading="whitted", shadow_samples=4, **o) for o in options]
    same(frames, adapter)
    assert frames[0].rays["reflection"] > 0 and frames[0].rays["refraction"] > 0


def test_a_mesh_past_the_storage_buffer_limit_is_refused_naming_it(adapter):
    """A mesh whose rows pass the adapter's largest storage buffer: one line
    naming the limit (the device's own, as requested), before any upload."""
    limits = {"max-storage-buffer-binding-size": 1 << 20, "max-buffer-size": 1 << 30,
              "max-texture-dimension-2d": 8192}  # fmt: skip
    too_many = (1 << 20) // (compute.TRIANGLE_FLOATS * 4) + 1
    with pytest.raises(RaybenchError, match=r"the triangles need .*max-storage-buffer-binding-size: 1 MiB"):
        compute.check_frame_fits(W, H, too_many, (8, 8), limits, "bvh", "triangle")
    compute.check_frame_fits(W, H, too_many - 1, (8, 8), limits, "bvh", "triangle")
    device = adapters.request_device(adapters.choose(adapter))
    largest = min(device.limits["max-storage-buffer-binding-size"], device.limits["max-buffer-size"])
    if largest > 1 << 28:
        return  # a mesh past it would take more memory than a test should
    huge = np.zeros((TRI_NA, largest // (compute.TRIANGLE_FLOATS * 4) + 1), np.float32)  # pages never touched
    with pytest.raises(RaybenchError, match="max-storage-buffer-binding-size|max-buffer-size"):
        backends.tracer("wgpu", huge, W, H, primitive="triangle", adapter=adapter)


def test_a_mesh_is_not_moved(adapter):
    """update moves spheres; a mesh is traced as it was given, as on the cpu."""
    leaves = mesh_scene(icosphere()).triangles
    tracer = backends.tracer("wgpu", leaves, 8, 8, primitive="triangle", adapter=adapter, build="gpu")
    try:
        with pytest.raises(RaybenchError, match="update: moves spheres"):
            tracer.update(leaves)
    finally:
        tracer.close()
