"""Spheres and triangles in one scene on wgpu (mixed.wgsl: sphere.wgsl's and
triangle.wgsl's answers under prefixes, each of the walks' names
dispatching on a primitive's tag), held to references of their own:
- the thesis's frame: test_mixed's float64 brute force over both kinds (the
  primitive each ray hits) and a float64 picture of the thesis's shading of
  either kind, on test_mixed's scene (three spheres, a floor, an icosphere)
  and on the SPD's sphereflake (balls, size 2) on its floor, through the
  host's tree, the GPU builder's, brute force and the packet walk;
- Whitted: a float64 picture of one point light's diffuse light, with the
  shadows each kind casts on the other, by pixel through either tree, by
  wavefront and by brute force; mirrors and glass (the mixed example):
  every way of tracing it one frame, and the cpu's frame (slow: the cpu
  compiles its mixed Whitted kernels, minutes from an empty cache);
- the GPU builder's tree over both kinds: valid, its leaves the Python's.
test_mixed_wgsl.py holds mixed.wgsl's answers to the sphere's and the
triangle's own shaders'. Frames are one to the byte on a CPU adapter
(test_triangle_wgpu.same); on a GPU, whose compiler may fuse a product into
a sum, within the tolerances that test states.

These tests skip where wgpu finds no adapter at all, except where
RAYBENCH_REQUIRE_WGPU=1 (CI sets it): there that is a failure.
"""

from __future__ import annotations

import numpy as np
import pytest
from test_mixed import both_reference, scenes
from test_triangle_render import reference, to_bytes
from test_triangle_wgpu import same

from raybench import Light, Scene, bvh, layout, render
from raybench.backends.wgpu import adapters, compute
from raybench.backends.wgpu import build as gpu_build
from raybench.examples import path as example
from raybench.formats import spd
from raybench.kernels.primitives import mixed
from raybench.layout import BLUE, RED, TRI_RED
from raybench.meshes import Mesh
from raybench.scene_meshes import SceneMesh, mixed_leaves

pytestmark = pytest.mark.gpu

W, H = 48, 32
PLAIN = mixed.make(lambda f: f)  # the functions as plain Python: njit compiles the same source


def wgpu(scene, adapter, width=W, height=H, **options):
    return render(scene, None, width, height, device="wgpu", adapter=adapter, **options)


def on_cpu(adapter) -> bool:
    """A CPU adapter rounds every operation to float32 as the references'
    float32 twins do: the reference's primitive on every clear pixel; a GPU
    may fuse, and tip a ray at a hair from an outline (99.5%)."""
    return adapters.choose(adapter).type == "CPU"


def balls() -> Scene:
    """The SPD's sphereflake of size 2 (91 spheres) on its floor: the floor
    polygon (NFF.triangles' fan of two triangles) as a mesh of its fill's colour."""
    made = spd.balls(2)
    fans = made.triangles()
    corners = np.float32(fans.corners.reshape(-1, 3))
    floor = Mesh(corners, np.arange(len(corners), dtype=np.int32).reshape(-1, 3))
    colour, material = made.fills[int(fans.fill[0])].material()
    return made.scene().replaced(meshes=[SceneMesh(floor, colour, material)])


def thesis_picture(scene: Scene, width: int, height: int):
    """The thesis's picture of both kinds in float64: a sphere's colour -
    (r - d) / r (d the half-chord), a triangle's colour - (1 - |n.D|), the
    gradient where a ray hits nothing; with both_reference's index and clear."""
    index, _t, clear, origin, dirs = both_reference(scene, width, height)
    n = len(scene)
    rgb = np.zeros((len(dirs), 3))
    sphere = (index >= 0) & (index < n)
    s = index[sphere]
    c, r = scene.spheres[:3, s].T.astype(np.float64), scene.spheres[3, s].astype(np.float64)
    eo = c - origin
    v = np.einsum("rk,rk->r", eo, dirs[sphere])
    d = np.sqrt(np.maximum(r**2 - ((eo**2).sum(axis=1) - v**2), 0))
    rgb[sphere] = scene.spheres[RED : BLUE + 1, s].T - ((r - d) / r)[:, None]
    triangle = index >= n
    _index, _t, normal, _margin = reference(scene.triangles, origin, dirs)
    cos = np.abs(np.einsum("rk,rk->r", normal[triangle], dirs[triangle]))
    rgb[triangle] = scene.triangles[TRI_RED : TRI_RED + 3, index[triangle] - n].T - (1 - cos)[:, None]
    xs, ys = np.meshgrid(np.arange(width), np.arange(height))
    x, y = xs.ravel().astype(np.float64), ys.ravel().astype(np.float64)
    rgb[index < 0] = np.stack([x / 1024, y / 1024, x / 786], axis=1)[index < 0]
    return index, clear, to_bytes(rgb).reshape(height, width, 3)


@pytest.mark.parametrize("which", ["spheres, a floor and an icosphere", "balls 2 on its floor"])
def test_thesis_frames_are_the_float64_reference_every_way(adapter, which):
    """The host's tree, the GPU builder's, brute force and (where the adapter
    has subgroups) the packet walk: the reference's primitive on every pixel
    clear of an outline or a tie, its colour within a step on 99.5% of the
    pixels, and one frame."""
    scene, (width, height) = (scenes()[0], (W, H)) if which.startswith("spheres") else (balls(), (64, 48))
    index, clear, expected = thesis_picture(scene, width, height)
    kinds = index[clear & (index >= 0)]
    assert (kinds < len(scene)).sum() > 50 and (kinds >= len(scene)).sum() > 50  # both kinds are seen
    options = [{}, {"build": "gpu"}, {"accel": "none"}]
    if compute.PACKET_FEATURE in adapters.choose(adapter).adapter.features:
        options.append({"walk": "packet"})
    frames = [wgpu(scene, adapter, width, height, **o) for o in options]
    assert frames[0].device == "wgpu"
    hits = frames[0].hits.ravel()
    agree = (hits[clear] == index[clear]).mean()
    assert agree == 1.0 if on_cpu(adapter) else agree >= 0.995
    close = (np.abs(frames[0].image.astype(int) - expected) <= 1).all(axis=2)
    assert close.mean() >= 0.995, close.mean()
    same(frames, adapter)


def segment_blocked(scene: Scene, points, to, dist, own):
    """Whether the float64 segment from each point along the unit `to` for
    `dist` meets a sphere or a triangle other than the point's own (`own`:
    the index of both kinds), by which kind, and whether it passes clear of
    every outline (a shadow rounding cannot change)."""
    n = len(scene)
    c, r = scene.spheres[:3].T.astype(np.float64), scene.spheres[3].astype(np.float64)
    eo = c[None] - points[:, None]  # (R, N, 3)
    v = np.einsum("rnk,rk->rn", eo, to)
    disc = r**2 - ((eo**2).sum(axis=2) - v**2)
    near = v - np.sqrt(np.maximum(disc, 0))
    mine = np.arange(n)[None] == own[:, None]
    by_sphere = ((disc >= 0) & (near > 0) & (near < dist[:, None]) & ~mine).any(axis=1)
    ahead = (v > 0) & (v < dist[:, None] + r) & ~mine
    clear = ~(ahead & (np.abs(disc) / r**2 < 1e-3)).any(axis=1)
    corners = scene.triangles[:9].astype(np.float64).T.reshape(-1, 3, 3)
    a, e1, e2 = corners[:, 0], corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0]
    p = np.cross(to[:, None], e2[None])  # (R, F, 3)
    det = np.einsum("fk,rfk->rf", e1, p)
    s = points[:, None] - a[None]
    with np.errstate(divide="ignore", invalid="ignore"):
        bu = np.einsum("rfk,rfk->rf", s, p) / det
        q = np.cross(s, e1[None])
        bv = np.einsum("rk,rfk->rf", to, q) / det
        t = np.einsum("fk,rfk->rf", e2, q) / det
        inside = np.minimum(np.minimum(bu, bv), 1 - bu - bv)
    mine = (np.arange(len(corners)) + n)[None] == own[:, None]
    crossing = np.isfinite(t) & (t > 1e-9) & (t < dist[:, None]) & ~mine
    by_triangle = (crossing & (inside >= 0)).any(axis=1)
    clear &= ~(crossing & (np.abs(inside) < 1e-3)).any(axis=1)
    return by_sphere, by_triangle, clear


def whitted_picture(scene: Scene, light: Light):
    """Whitted's picture of matte primitives under one point light in
    float64: colour times (ambient + the light's power times max(n.L, 0)
    where the segment to the light is clear), n the hit's normal turned to
    the viewer; the gradient where a ray hits nothing. With the rays whose
    hit and shadow rounding cannot change, and which kind shadows each."""
    index, t, clear, origin, dirs = both_reference(scene)
    n = len(scene)
    point = origin + np.where(index >= 0, t, 0)[:, None] * dirs
    normal = np.zeros_like(point)
    sphere, triangle = (index >= 0) & (index < n), index >= n
    s = index[sphere]
    normal[sphere] = (point[sphere] - scene.spheres[:3, s].T) / scene.spheres[3, s][:, None]
    normal[triangle] = reference(scene.triangles, origin, dirs)[2][triangle]
    normal *= -np.sign(np.einsum("rk,rk->r", normal, dirs))[:, None]
    to = np.asarray(light.position, np.float64) - point
    dist = np.linalg.norm(to, axis=1)
    to /= dist[:, None]
    facing = np.maximum(np.einsum("rk,rk->r", normal, to), 0)
    by_sphere, by_triangle, shadow_clear = segment_blocked(scene, point, to, dist, index)
    lit = facing * ~(by_sphere | by_triangle)
    colour = np.zeros_like(point)
    colour[sphere] = scene.spheres[RED : BLUE + 1, s].T
    colour[triangle] = scene.triangles[TRI_RED : TRI_RED + 3, index[triangle] - n].T
    power = np.asarray(light.color) * light.intensity
    rgb = colour * (np.asarray(scene.ambient) + lit[:, None] * power)
    xs, ys = np.meshgrid(np.arange(W), np.arange(H))
    miss = np.stack([xs.ravel() / 1024, ys.ravel() / 1024, xs.ravel() / 786], axis=1)
    picture = to_bytes(np.where((index >= 0)[:, None], rgb, miss)).reshape(H, W, 3)
    shadowed = (index >= 0) & (facing > 0)
    return picture, index, clear & shadow_clear, shadowed & by_sphere, shadowed & by_triangle


def test_whitted_shadows_of_each_kind_on_the_other_are_the_float64_reference(adapter):
    """One point light low on the right of test_mixed's scene, everything
    matte: by pixel through either tree, by wavefront and by brute force,
    one frame; on every pixel whose hit and shadow ray pass clear of an
    outline, the reference's primitive and (on 99.5% of them, and on every
    shadowed one) its colour within a step. The spheres shadow the floor and
    the icosphere, and the icosphere a sphere: shadow rays that leave one
    kind and meet the other."""
    light = Light(position=(6.0, 0.3, 6.0), color=(1.0, 1.0, 1.0), intensity=1.0)
    scene = scenes(lights=[light])[0]
    expected, index, clear, by_sphere, by_triangle = whitted_picture(scene, light)
    on_sphere, n = (index >= 0) & (index < len(scene)), len(scene)
    assert clear.mean() > 0.9
    assert (clear & by_sphere & (index >= n)).sum() > 10 and (clear & by_triangle & on_sphere).sum() > 10
    options = [{}, {"build": "gpu"}, {"schedule": "wavefront"}, {"accel": "none"}]
    frames = [wgpu(scene, adapter, shading="whitted", **o) for o in options]
    same(frames, adapter)
    assert frames[0].rays["shadow"] > 0 and frames[0].rays["reflection"] == 0
    hits = frames[0].hits.ravel()
    agree = (hits[clear] == index[clear]).mean()
    assert agree == 1.0 if on_cpu(adapter) else agree >= 0.995
    close = (np.abs(frames[0].image.astype(int) - expected) <= 1).all(axis=2).ravel()
    assert close[clear].mean() >= 0.995, close[clear].mean()
    assert close[clear & (by_sphere | by_triangle)].all()


@pytest.fixture(scope="module")
def example_frames(adapter):
    """The mixed example (a mirror ball and a glass one on a mirroring floor
    beside an icosahedron, an area light) by pixel through either tree, by
    wavefront and by brute force."""
    scene = Scene.load(example("mixed"))
    options = [{}, {"build": "gpu"}, {"schedule": "wavefront"}, {"accel": "none"}]
    return scene, [wgpu(scene, adapter, shading="whitted", **o) for o in options]


def test_mirrors_and_glass_trace_alike_every_way(adapter, example_frames):
    """Reflected and refracted rays cast from either kind, and every way of
    tracing them one frame and one count of rays."""
    _scene, frames = example_frames
    same(frames, adapter)
    assert frames[0].rays["reflection"] > 0 and frames[0].rays["refraction"] > 0
    assert len(np.unique(frames[0].hits)) > 5


def test_a_kind_no_ray_meets_leaves_the_other_kinds_frame(adapter, example_frames):
    """The mixed example's spheres with a speck of a triangle that no ray
    meets (far off, away from the light), and its meshes with such a speck
    of a sphere: Whitted's frames of the sphere-only and the mesh-only
    scenes (sphere.wgsl's and triangle.wgsl's own shaders): the hits (a
    mesh's after the one sphere), the bytes and the rays cast. Every path of
    a glass ball's rays (into it, inside it, out of it: meets_own), a
    mirror's and a shadow's through mixed.wgsl is the kind's own."""
    scene, _frames = example_frames
    far = np.float32([2000.0, -3000.0, -1500.0])
    speck = Mesh(far + np.float32([[0, 0, 0], [1e-3, 0, 0], [0, 1e-3, 0]]), np.int32([[0, 1, 2]]))
    spheres_only = scene.replaced(meshes=[])
    meshes_only = scene.replaced(centers=np.zeros((0, 3)), radii=[], colors=np.zeros((0, 3)), materials=None)
    cases = (
        (scene.replaced(meshes=[SceneMesh(speck)]), spheres_only, 0),
        (meshes_only.replaced(centers=[far], radii=[1e-3], colors=[[1, 1, 1]], materials=None), meshes_only, 1),
    )
    for both, alone, shift in cases:
        assert both.traced().kind == "mixed" and alone.traced().kind != "mixed"
        got, want = (wgpu(s, adapter, shading="whitted") for s in (both, alone))
        assert (got.hits >= 0).sum() > 50 and want.rays["shadow"] > 0
        want.hits[want.hits >= 0] += shift
        same([want, got], adapter)


@pytest.mark.slow
def test_mirrors_and_glass_are_the_cpus_frame(example_frames):
    """The cpu's frame of the mixed example (its Numba kernels over
    kernels/primitives/mixed.py): the same primary hits on 99.5% of the
    pixels and the colours within a step there."""
    scene, frames = example_frames
    cpu = render(scene, None, W, H, device="cpu", shading="whitted", threads=2)
    assert (cpu.hits == frames[0].hits).mean() >= 0.995
    close = (np.abs(cpu.image.astype(int) - frames[0].image.astype(int)) <= 1).all(axis=2)
    assert close.mean() >= 0.995, close.mean()


@pytest.mark.parametrize("quality", gpu_build.QUALITIES)
def test_gpu_tree_over_both_kinds_is_valid(adapter, quality):
    """The GPU's tree over the sphereflake, its floor and test_mixed's scene
    (mixed_build.wgsl: each primitive's box its kind's own): every primitive
    in one leaf, its leaf row the Python's copy_leaf (a sphere's four values
    and zeros, or a triangle's nine, then the tag) in leaf order, each leaf's
    box around its primitives' padded boxes (the Python's extent), each
    child's inside its parent's."""
    import wgpu as wgpu_api

    parts = [balls(), scenes()[0]]
    spheres = np.concatenate([p.spheres for p in parts], axis=1)
    triangles = np.concatenate([p.triangles for p in parts], axis=1)
    leaves = mixed_leaves(spheres, triangles)
    n = leaves.shape[1]
    device = adapters.request_device(adapters.choose(adapter))
    usage = wgpu_api.BufferUsage.STORAGE
    rows = device.create_buffer_with_data(data=compute.mixed_rows(leaves).tobytes(), usage=usage)
    builder = gpu_build.Builder(device, rows, n, quality=quality, kernels=gpu_build.Kernels(device, "mixed"))
    tree = builder.to_host(builder.run(builder.encode_build).depth)
    assert sorted(tree.order.tolist()) == list(range(n))
    copied = np.zeros((layout.MIX_LEAF_ROWS, n), np.float32)
    for at, k in enumerate(tree.order):
        PLAIN.copy_leaf(leaves, k, copied, at)
    assert np.array_equal(tree.ordered, copied)
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
                cx, cy, cz, hx, hy, hz = PLAIN.extent(leaves, k)
                assert (lo <= np.float32([cx - hx, cy - hy, cz - hz])).all()
                assert (hi >= np.float32([cx + hx, cy + hy, cz + hz])).all()
    assert (seen == 1).all()
