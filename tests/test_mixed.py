"""Spheres and triangles in one scene (kernels/primitives/mixed.py, one tree
of typed leaves), on the cpu, held to references of their own:
- a float64 NumPy brute force over both kinds (the spheres' roots, the
  triangles' Moller-Trumbore): which primitive each primary ray hits, and t;
- the sphere-only and mesh-only renders of the same primitives, wherever a
  pixel sees one kind only (the thesis's shading is the hit's own);
- Whitted: a sphere's shadow falls on a triangle floor, where the float64
  segment to the light passes through the sphere, and nowhere else.
The mixed kind's answers are the sphere's and the triangle's own; every
device traces it (test_mixed_cuda.py, test_mixed_wgpu.py), and a device
that did not would refuse it in one line."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh
from PIL import Image
from test_triangle_render import rays64, reference

from raybench import Camera, Light, RaybenchError, Scene, backends, render
from raybench.bvh import build
from raybench.cli import run
from raybench.kernels import traverse
from raybench.kernels.constants import FAR
from raybench.kernels.primitives import KINDS, mixed, sphere, triangle
from raybench.layout import STACK
from raybench.meshes import Mesh
from raybench.scene_meshes import SceneMesh, mixed_leaves

W, H = 48, 32
PLAIN = lambda f: f  # noqa: E731 - the functions as plain Python: njit compiles the same source
FLOOR = Mesh(
    np.float32([[-6, -1, 2], [6, -1, 2], [6, -1, 16], [-6, -1, 16]]), np.int32([[0, 2, 1], [0, 3, 2]])
)  # y = -1, z from 2 to 16


def ball() -> Mesh:
    shape = trimesh.creation.icosphere(subdivisions=1, radius=0.8)
    return Mesh(np.float32(shape.vertices + [1.3, 0.1, 6.0]), np.int32(shape.faces))


def scenes(lights=()):
    """(both, spheres only, meshes only): three spheres, a floor and an icosphere mesh."""
    centers, radii = [[-1.3, 0.0, 6.0], [0.0, 0.4, 9.0], [0.2, -0.6, 4.5]], [0.8, 1.2, 0.3]
    colours = [[0.9, 0.3, 0.2], [0.2, 0.8, 0.3], [0.9, 0.9, 0.2]]
    meshes = [SceneMesh(FLOOR, (0.7, 0.7, 0.8)), SceneMesh(ball(), (0.3, 0.4, 0.9))]
    camera = Camera((0.0, 0.5, 0.0), (0.0, 0.0, 6.0))
    both = Scene(centers, radii, colours, camera, meshes=meshes, lights=lights)
    spheres = Scene(centers, radii, colours, camera, lights=lights)
    only_meshes = Scene(np.zeros((0, 3)), [], np.zeros((0, 3)), camera, meshes=meshes, lights=lights)
    return both, spheres, only_meshes


def sphere_reference(spheres: np.ndarray, origin, dirs):
    """Each ray's nearest sphere in float64 (-1 for none), its t, and how
    clear of a sphere's outline or of a tie the ray passes (the discriminant
    over r^2)."""
    c, r = spheres[:3].T.astype(np.float64), spheres[3].astype(np.float64)
    eo = c - origin
    v = dirs @ eo.T  # (R, N)
    disc = r**2 - ((eo**2).sum(axis=1)[None] - v**2)
    t = np.where(disc >= 0, v - np.sqrt(np.maximum(disc, 0)), np.inf)
    t = np.where(t > 0, t, np.inf)
    nearest = np.argmin(t, axis=1)
    rows = np.arange(len(dirs))
    got = np.isfinite(t[rows, nearest])
    return np.where(got, nearest, -1), t[rows, nearest], np.abs(disc[rows, nearest]) / r[nearest] ** 2


def both_reference(scene: Scene, width: int = W, height: int = H):
    """The float64 nearest hit over spheres and triangles: index as the
    mixed buffer numbers them (spheres, then triangles), t, and whether the
    ray passes clear of every outline and tie (a pixel rounding cannot
    change)."""
    origin, dirs = rays64(scene.camera, width, height)
    s_index, s_t, s_clear = sphere_reference(scene.spheres, origin, dirs)
    t_index, t_t, _normal, margin = reference(scene.triangles, origin, dirs)
    tri_first = t_t < s_t
    index = np.where(tri_first, np.where(t_index >= 0, t_index + len(scene), -1), s_index)
    t = np.minimum(s_t, t_t)
    both_hit = np.isfinite(s_t) & np.isfinite(t_t)
    with np.errstate(invalid="ignore"):  # inf - inf where both miss: not a tie
        tie = both_hit & (np.abs(s_t - t_t) <= 1e-4 * t)
    clear = (np.abs(margin) > 1e-4) & ((s_index < 0) | (s_clear > 1e-4)) & ~tie
    return index, t, clear, origin, dirs


def test_each_answer_is_the_kinds_own():
    """The mixed kind registers as a kind, and each of its answers on a
    sphere's or a triangle's column is that kind's own answer on its own
    buffer, bit for bit."""
    assert KINDS["mixed"] is mixed and mixed.LEAF_ROWS == 10 and mixed.PACKED_WORDS == 5
    m, s, t = mixed.make(PLAIN), sphere.make(PLAIN), triangle.make(PLAIN)
    both = scenes()[0]
    buffer, n = mixed_leaves(both.spheres, both.triangles), len(both)
    origin, dirs = rays64(both.camera, 8, 6)
    o, dirs = np.float32(origin), np.float32(dirs)
    for k in range(buffer.shape[1]):
        own, buf, i = (s, both.spheres, k) if k < n else (t, both.triangles, k - n)
        assert m.extent(buffer, k) == own.extent(buf, i) and m.colour(buffer, k) == own.colour(buf, i)
        assert m.rim(buffer, k) == own.rim(buf, i)
        for d in dirs:
            got = m.hit(buffer, k, *o, *d)
            assert got == own.hit(buf, i, *o, *d)
            assert m.hit_from(m.seen_from(m.read(buffer, k), *o), *d) == got
            if got[0] > 0:
                assert m.surface(*o, *d, got[0], k, buffer) == own.surface(*o, *d, got[0], i, buf)
    assert np.array_equal(mixed.centres(buffer)[:, :n], sphere.centres(both.spheres))
    assert np.array_equal(mixed.centres(buffer)[:, n:], triangle.centres(both.triangles))


def test_the_walk_finds_the_float64_nearest_of_both_kinds():
    """The one tree of typed leaves, walked as plain Python (the source
    njit compiles): the float64 reference's primitive on every ray clear of
    an outline or a tie, and its t to float32's precision."""
    both = scenes()[0]
    buffer = mixed_leaves(both.spheres, both.triangles)
    tree = build(buffer, threads=1, primitive=mixed)
    walk = traverse.make(PLAIN, mixed.make(PLAIN)).walk
    index, t, clear, origin, dirs = both_reference(both)
    stack = np.zeros(STACK, np.int32), np.zeros(STACK, np.float32)
    got, got_t = [], []
    for d in np.float32(dirs):
        hit, t_hit, _ = walk(*np.float32(origin), *d, FAR, False, False, -1, False, tree.nodes, tree.links,
                             tree.ordered, tree.order, *stack)  # fmt: skip
        got.append(hit)
        got_t.append(t_hit)
    got, got_t = np.array(got), np.array(got_t, np.float64)
    kinds = index[clear & (index >= 0)]
    assert (kinds < len(both)).sum() > 50 and (kinds >= len(both)).sum() > 50  # both kinds are seen
    assert np.array_equal(got[clear], index[clear])
    seen = clear & (index >= 0)
    assert np.allclose(got_t[seen], t[seen], rtol=1e-5)


@pytest.fixture(scope="module")
def thesis():
    """The three scenes' thesis frames on the cpu (the 4-wide packets)."""
    return [render(s, None, W, H, device="cpu", threads=2) for s in scenes()]


def test_thesis_frame_hits_the_float64_reference(thesis):
    index, _t, clear, _o, _d = both_reference(scenes()[0])
    assert np.array_equal(thesis[0].hits.ravel()[clear], index[clear])


def test_thesis_frame_is_the_one_kind_renders_where_one_kind_is_seen(thesis):
    """A pixel whose nearest hit is a sphere is the sphere-only render's
    pixel wherever that render hits the same sphere (the thesis's shading is
    the hit's own), a triangle's the mesh-only render's, and a miss both's
    background; the binary tree's walk and brute force give the same frame."""
    both, spheres, meshes = thesis
    n = len(scenes()[0])
    hits = both.hits
    on_sphere = (hits >= 0) & (hits < n) & (spheres.hits == hits)
    on_mesh = (hits >= n) & (meshes.hits == hits - n)
    missed = (hits < 0) & (spheres.hits < 0) & (meshes.hits < 0)
    assert on_sphere.sum() > 50 and on_mesh.sum() > 50 and missed.sum() > 20
    assert (on_sphere | on_mesh | missed).mean() > 0.95  # the rest: a sphere hidden behind a triangle or the reverse
    assert (both.image[on_sphere] == spheres.image[on_sphere]).all()
    assert (both.image[on_mesh] == meshes.image[on_mesh]).all()
    assert (both.image[missed] == spheres.image[missed]).all()
    for options in ({"tree_width": 2}, {"accel": "none", "kernel": "simple"}):
        other = render(scenes()[0], None, W, H, device="cpu", threads=2, **options)
        assert (other.hits == both.hits).all() and (other.image == both.image).all(), options


def test_whitted_through_the_wide_tree_is_the_binary_trees_frame():
    """Under Whitted shading the default, the 4-wide tree (primary rays as
    packets, shadow rays and bounces alone: mixed.SHADOW_PACKETS is False),
    gives the binary tree's frame, every ray alone, bit for bit."""
    assert not mixed.SHADOW_PACKETS
    area, point = Light(position=(-3.0, 6.0, 2.0), radius=0.5), Light(position=(3.0, 4.0, 1.0))
    scene = scenes(lights=(area, point))[0]
    frames = [render(scene, None, W, H, device="cpu", shading="whitted", threads=2, tree_width=w) for w in (4, 2)]
    assert (frames[0].hits >= 0).mean() > 0.3 and frames[0].rays["shadow"] > 2 * (frames[0].hits >= 0).sum()
    assert (frames[0].hits == frames[1].hits).all() and (frames[0].image == frames[1].image).all()


@pytest.mark.slow
def test_a_spheres_shadow_falls_on_the_triangle_floor():
    """Whitted, one point light above and behind a sphere over the floor: a
    floor pixel is darker than the floor alone's wherever the float64
    segment from its point to the light passes well inside the sphere, and
    the same wherever it passes well clear of it."""
    light = Light(position=(-3.0, 6.0, 16.0), color=(1.0, 1.0, 1.0), intensity=1.0)
    centre, r = np.array([0.0, 0.5, 8.0]), 1.0
    camera = Camera((0.0, 3.0, 0.0), (0.0, -1.0, 8.0))
    shaded = Scene([centre], [r], [[0.8, 0.2, 0.2]], camera, meshes=[SceneMesh(FLOOR, (0.8, 0.8, 0.8))],
                   lights=[light])  # fmt: skip
    floor = Scene(np.zeros((0, 3)), [], np.zeros((0, 3)), camera, meshes=[SceneMesh(FLOOR, (0.8, 0.8, 0.8))],
                  lights=[light])  # fmt: skip
    got = render(shaded, None, W, H, device="cpu", shading="whitted", threads=2)
    alone = render(floor, None, W, H, device="cpu", shading="whitted", threads=2)
    origin, dirs = rays64(camera, W, H)
    index, t, _normal, margin = reference(floor.triangles, origin, dirs)
    point = origin + np.where(index >= 0, t, 0)[:, None] * dirs
    to_light = np.asarray(light.position) - point
    along = np.clip(np.einsum("rk,rk->r", centre - point, to_light) / (to_light**2).sum(axis=1), 0, 1)
    gap = np.linalg.norm(point + along[:, None] * to_light - centre, axis=1)  # the segment's distance to the centre
    on_floor = (got.hits.ravel() == index + 1) & (index >= 0) & (np.abs(margin) > 1e-4)
    dark, lit = on_floor & (gap < 0.9 * r), on_floor & (gap > 1.1 * r)
    assert dark.sum() > 20 and lit.sum() > 100
    mine, theirs = got.image.reshape(-1, 3).astype(int), alone.image.reshape(-1, 3).astype(int)
    assert (mine[dark] < theirs[dark]).all()
    assert (np.abs(mine[lit] - theirs[lit]) <= 1).all()
    assert got.rays["shadow"] > 0


def test_a_device_without_the_mixed_kind_would_refuse_it_in_one_line(monkeypatch):
    """Every device traces spheres and triangles together; one that did not
    (KIND_DEVICES without it) refuses them in one line naming those that do."""
    both = scenes()[0]
    buffer = both.traced().leaves
    assert both.traced().kind == "mixed" and both.traced().noun == "primitives"
    assert backends.KIND_DEVICES["mixed"] == ("cpu", "cuda", "wgpu")
    backends._check_kind("wgpu", buffer, "mixed")
    monkeypatch.setitem(backends.KIND_DEVICES, "mixed", ("cpu", "cuda"))
    said = "device wgpu: scenes of spheres and meshes together are traced on cpu, cuda only so far"
    with pytest.raises(RaybenchError, match=said) as e:
        backends._check_kind("wgpu", buffer, "mixed")
    assert "\n" not in str(e.value)


def test_render_a_version_3_file_of_both_kinds_end_to_end(tmp_path, capsys, adapter):
    """raybench render --scene FILE.json of spheres and meshes: the PNG is
    render()'s frame, on the cpu and on wgpu, whose frame is the cpu's (on
    a CPU adapter; within a step on 99.5% of the pixels on a GPU)."""
    both = scenes()[0]
    path = tmp_path / "both.json"
    both.save(path)
    out = tmp_path / "both.png"
    assert run(["render", "--scene", str(path), "-o", str(out), "--size", f"{W}x{H}", "--threads", "2"]) == 0
    capsys.readouterr()
    cpu = render(both, None, W, H, device="cpu", threads=2).image
    assert np.array_equal(np.asarray(Image.open(out)), cpu)
    out = tmp_path / "wgpu.png"
    command = ["render", "--scene", str(path), "-o", str(out), "--size", f"{W}x{H}", "--device", "wgpu"]
    assert run([*command, "--adapter", adapter]) == 0
    capsys.readouterr()
    image = np.asarray(Image.open(out))
    assert np.array_equal(image, render(both, None, W, H, device="wgpu", adapter=adapter).image)
    assert (np.abs(image.astype(int) - cpu.astype(int)) <= 1).all(axis=2).mean() >= 0.995


@pytest.mark.slow
def test_the_clusters_tiles_are_the_single_process_frame(thesis):
    """raybench.cluster's workers trace a scene of both kinds in tiles of
    rows: the single process's frame, bit for bit (the workers load the
    kernels the thesis fixture compiled into the disk cache)."""
    pytest.importorskip("distributed")
    from raybench import cluster

    with cluster.Cluster(workers=1, device="cpu") as running:
        running.client.wait_for_workers(1, timeout=120)
        frame = cluster.render(running.client, scenes()[0], None, W, H, device="cpu", rows=8)
    assert np.array_equal(frame.image, thesis[0].image) and np.array_equal(frame.hits, thesis[0].hits)
