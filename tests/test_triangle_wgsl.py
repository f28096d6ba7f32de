"""triangle.wgsl against its Python twin (kernels/primitives/triangle.py),
function by function, on a CPU adapter (lavapipe), in the manner of
test_wgsl_parity.py: the WGSL piece on its own, an entry point a function
that reads each lane's arguments from a buffer and writes its results.

WGSL has no float64, where the Python works out the edge functions, det, T
and the normal (triangle.wgsl's header). What is held:
- hit or miss: the same on every lane (the edge functions' signs are exact
  in both, from the same float32 sheared vertices), degenerate triangles
  and rays aimed at vertices and edges included;
- t within 4 float32 ulps of the Python's, and the cosine within 4 epsilons
  (float32 det, T and normal where the Python rounds once from float64);
- the sheared set-up (permute), the boxes, meets_own and rim: the very bits;
- surface (the point, the normal on the ray's side, cos_i, the back face),
  the plane's or the corners' normals blended: the point's bits, the normal
  and cos_i within a few epsilons (float32 barycentrics and normal);
- the builders' twins (triangle_build.wgsl, after triangle_box.wgsl, as
  build.py assembles them): extent and leaf_row, the very bits of the
  Python's extent and copy_leaf.
"""

from __future__ import annotations

import re
from importlib import resources

import numpy as np
import pytest
from wgsl_harness import IN, cpu_adapter, dispatch, entry_points

from raybench import layout
from raybench.backends.wgpu import adapters, compute, shader
from raybench.backends.wgpu import build as gpu_build
from raybench.kernels.primitives import triangle

pytestmark = pytest.mark.gpu

F32 = np.float32
PLAIN = triangle.make(lambda f: f)
N = 2048
# name: (WGSL body; the lane's arguments are o (0-2) and d (3-5); triangle k is lane k's)
CASES = {
    "hit": "let r = hit(k, v3(0u, i), v3(3u, i)); put(0u, i, r.x); put(1u, i, r.y);",
    "leaf_hit": "let r = leaf_hit(k, v3(0u, i), v3(3u, i)); put(0u, i, r.x); put(1u, i, r.y);",
    "hit_ahead": "let r = hit_ahead(k, v3(0u, i), v3(3u, i), false); put(0u, i, r.x); put(1u, i, r.y);"
    " let s = hit_ahead(k, v3(0u, i), v3(3u, i), true); put(2u, i, s.x);",
    "hit_from": "let r = hit_ahead_from(from_origin(k, v3(0u, i)), v3(3u, i), false);"
    " put(0u, i, r.x); put(1u, i, r.y);",
    "permute": "let p = permute(v3(0u, i), k % 3); put(0u, i, p.x); put(1u, i, p.y); put(2u, i, p.z);",
    "bounds": "let b = bounds(k); put(0u, i, b[0].x); put(1u, i, b[0].y); put(2u, i, b[0].z);"
    " put(3u, i, b[1].x); put(4u, i, b[1].y); put(5u, i, b[1].z);",
    "meets_own": "put(0u, i, select(0.0, 1.0, meets_own(true) || meets_own(false))); put(1u, i, rim(k));",
    # brute force: the nearest of every triangle of the scene's buffer, for the watertight test
    "nearest": "var best = -1.0; for (var j = 0; j < i32(arrayLength(&spheres)); j++) {"
    " let r = hit(j, v3(0u, i), v3(3u, i)); if (r.x > 0.0 && (best < 0.0 || r.x < best)) { best = r.x; } }"
    " put(0u, i, best);",
    # the lane's ray (0-5) met at t (6)
    "surface": "let h = surface(v3(0u, i), v3(3u, i), arg(6u, i), k); put(0u, i, h.p.x); put(1u, i, h.p.y);"
    " put(2u, i, h.p.z); put(3u, i, h.n.x); put(4u, i, h.n.y); put(5u, i, h.n.z); put(6u, i, h.cos_i);"
    " put(7u, i, flag(h.inside));",
}
# The builders' answers, on the build's own module (binding 1: the scene's rows)
BUILD_CASES = {
    "extent": "let e = extent(u32(k)); put(0u, i, e.centre.x); put(1u, i, e.centre.y); put(2u, i, e.centre.z);"
    " put(3u, i, e.half_size.x); put(4u, i, e.half_size.y); put(5u, i, e.half_size.z);",
    "leaf_row": "let r = leaf_row(u32(k)); for (var j = 0u; j < 9u; j++) { put(j, i, r[j]); }",
}
# common.wgsl's binding of the scene's buffer, which triangle.wgsl reads as its struct Sphere
SCENE = "@group(0) @binding(1) var<storage, read> spheres: array<Sphere>;\n"


@pytest.fixture(scope="module")
def device(adapter):
    return adapters.request_device(cpu_adapter())


@pytest.fixture(scope="module")
def module(device):
    pieces = shader.KIND_PIECES["triangle"]
    folder = resources.files("raybench.backends.wgpu")
    text = SCENE + "\n".join(folder.joinpath(p).read_text(encoding="utf-8") for p in pieces)
    for name, value in shader.BVH_CONSTANTS.items():
        text = text.replace(name, value)
    return device.create_shader_module(code=text + entry_points(CASES, N))


@pytest.fixture(scope="module")
def build_module(device):
    text = gpu_build.source("build_tree.wgsl", "triangle")
    return device.create_shader_module(code=text + entry_points(BUILD_CASES, N))


def run(device, module, name, lanes, buffer, results):
    """WGSL function case `name` on each lane: (results, N) float32."""
    rows = np.ascontiguousarray(buffer[: layout.TRI_ROWS].T, F32)  # triangle k's nine values at 9k
    body = CASES[name]
    given = {IN: np.ascontiguousarray(lanes, F32), 1: compute.triangle_rows(buffer), 5: rows}
    scene = re.search(r"(?<![\w])(hit(_ahead)?|surface)\(", body) is not None  # read_triangle's binding
    leaves = any(f in body for f in ("leaf_hit(", "from_origin(", "bounds("))  # read_leaf's
    uses = [b for b, used in ((IN, "arg(" in body or "v3(" in body), (1, scene), (5, leaves)) if used]
    return dispatch(device, module, name, {b: given[b] for b in uses}, results, N)


def unit(v):
    v = np.asarray(v, np.float64)
    with np.errstate(invalid="ignore"):  # a degenerate triangle's corners: no hit reads them
        return (v / np.linalg.norm(v, axis=-1, keepdims=True)).astype(F32)


def inputs(seed=41):
    """(buffer (9, N), lanes (6, N)): random triangles, each lane's ray aimed
    near its triangle; an eighth aimed exactly at a vertex or an edge's
    midpoint, an eighth degenerate (repeated or collinear grid vertices),
    some rays axis-aligned."""
    rng = np.random.default_rng(seed)
    centre = rng.uniform(-20, 20, (N, 1, 3))
    verts = centre + rng.uniform(-1, 1, (N, 3, 3)) * rng.uniform(0.01, 3, (N, 1, 1))
    e = N // 8
    grid = np.round(rng.uniform(-8, 8, (e, 1, 3)) * 4) / 4
    step = np.round(rng.uniform(-2, 2, (e, 1, 3)) * 4) / 4
    verts[e : 2 * e] = grid + step * np.array([0.0, 1.0, 3.0])[None, :, None]  # collinear
    verts[2 * e : 2 * e + e // 2, 1] = verts[2 * e : 2 * e + e // 2, 0]  # a repeated vertex
    verts = verts.astype(F32)
    w = rng.uniform(-0.3, 1.0, (N, 3))
    target = (w[:, :, None] * verts).sum(1) / w.sum(1, keepdims=True)
    target[:e] = verts[:e, 0]  # at a vertex
    target[3 * e : 4 * e] = (verts[3 * e : 4 * e, 0].astype(np.float64) + verts[3 * e : 4 * e, 1]) / 2
    o = (target + rng.normal(size=(N, 3)) * rng.uniform(0.5, 30, (N, 1))).astype(F32)
    d = unit(target - o)
    axis = slice(4 * e, 4 * e + e // 2)  # axis-aligned rays, aimed at the plane's point straight ahead
    d[axis] = 0
    d[axis, 2] = np.where(target[axis, 2] > o[axis, 2], 1, -1)
    buffer = np.ascontiguousarray(verts.reshape(N, 9).T)
    return buffer, np.ascontiguousarray(np.concatenate([o, d], 1).T)


def python(fn, lanes, buffer):
    return np.array([fn(buffer, k, *lanes[:, k]) for k in range(N)], np.float64).T


def test_hits_and_misses_agree(device, module):
    """Every hit test: the same hit or miss on every lane as the Python; t
    within 4 ulps, cos within 4 epsilons; and enough of each kind."""
    buffer, lanes = inputs()
    want = python(PLAIN.hit, lanes, buffer)
    assert (want[0] > 0).sum() > N // 4 and (want[0] <= 0).sum() > N // 4
    for name in ("hit", "leaf_hit", "hit_ahead", "hit_from"):
        got = run(device, module, name, lanes, buffer, 3 if name == "hit_ahead" else 2).astype(np.float64)
        hit = want[0] > 0
        assert ((got[0] > 0) == hit).all(), (name, np.flatnonzero((got[0] > 0) != hit)[:5])
        ulp = np.spacing(np.abs(want[0][hit]).astype(F32)).astype(np.float64)
        assert (np.abs(got[0][hit] - want[0][hit]) <= 4 * ulp).all(), name
        assert (np.abs(got[1][hit] - want[1][hit]) <= 4 * np.finfo(F32).eps).all(), name
        assert (got[0][~hit] == -1).all() and (got[1][~hit] == 0).all()
        if name == "hit_ahead":
            assert (got[2] == -1).all()  # the ray's own triangle: a miss


def test_bits_agree(device, module):
    """permute, the padded boxes, meets_own and rim: the very bits."""
    buffer, lanes = inputs(42)
    got = run(device, module, "permute", lanes, buffer, 3)
    want = np.array([PLAIN.permute(*lanes[:3, k], k % 3) for k in range(N)], F32).T
    assert (got == want).all()
    got = run(device, module, "bounds", lanes, buffer, 6)
    want = np.array([PLAIN.bounds(buffer, k) for k in range(N)], F32).T
    assert (got == want).all()
    got = run(device, module, "meets_own", lanes, buffer, 2)
    assert (got[0] == 0).all() and (got[1] == 1).all()


def test_watertight_icosphere(device, module):
    """Every ray from inside a subdivided icosphere hits it in WGSL too: rays
    from random points inside aimed at its vertices, its edges' midpoints
    and points along its edges, and rays from its centre."""
    trimesh = pytest.importorskip("trimesh")
    rng = np.random.default_rng(43)
    mesh = trimesh.creation.icosphere(subdivisions=3, radius=1.0)
    v = np.asarray(mesh.vertices, np.float64)
    edges = np.asarray(mesh.edges_unique)
    along = rng.uniform(0, 1, (N, 1))
    pick = rng.integers(0, len(edges), N)
    targets = np.concatenate([v, v[edges].mean(1), v[edges[pick, 0]] * (1 - along) + v[edges[pick, 1]] * along])
    targets = targets[:N].astype(F32)
    inside = rng.normal(size=(N, 3))
    inside *= rng.uniform(0, 0.9, (N, 1)) / np.linalg.norm(inside, axis=1, keepdims=True)
    inside[: N // 4] = 0.0  # from the centre
    o = inside.astype(F32)
    d = unit(targets.astype(np.float64) - o)
    buffer = np.ascontiguousarray(np.asarray(v, F32)[mesh.faces].reshape(len(mesh.faces), 9).T)
    got = run(device, module, "nearest", np.ascontiguousarray(np.concatenate([o, d], 1).T), buffer, 1)
    assert (got[0] > 0).all(), f"{(got[0] <= 0).sum()} of {N} rays slipped through"


def smooth(buffer, rng):
    """The buffer with its colour and corners' normals (TRI_SMOOTH_ROWS): each
    corner's normal the plane's turned a little, either way round; a quarter
    of the triangles with none (zeros), as compute.triangle_rows lays out a
    mesh without them."""
    n = buffer.shape[1]
    v = buffer.T.reshape(n, 3, 3).astype(np.float64)
    plane = np.cross(v[:, 1] - v[:, 0], v[:, 2] - v[:, 0])
    corners = plane[:, None, :] + rng.normal(size=(n, 3, 3)) * np.linalg.norm(plane, axis=1)[:, None, None] * 0.3
    corners *= rng.choice([-1.0, 1.0], (n, 1, 1))
    out = np.zeros((layout.TRI_SMOOTH_ROWS, n), F32)
    out[: layout.TRI_ROWS] = buffer
    out[layout.TRI_RED : layout.TRI_RED + 3] = rng.uniform(0, 1, (3, n))
    out[layout.TRI_NA :] = unit(corners).reshape(n, 9).T
    out[layout.TRI_NA :, : n // 4] = 0.0
    return out


def test_surface_is_the_pythons(device, module):
    """surface at each lane's hit: the point's very bits, the back face as the
    Python says, the normal and cos_i within 8 epsilons on 99% of the lanes
    and within 1e-4 on all; the corners' normals blended where the row has
    them, the plane's where not."""
    rng = np.random.default_rng(44)
    buffer, lanes = inputs(44)
    buffer = smooth(buffer, rng)
    t = python(PLAIN.hit, lanes, buffer)[0].astype(F32)
    hit = t > 0
    lanes = np.vstack([lanes, t])
    want = np.array([PLAIN.surface(*lanes[:7, k], k, buffer) for k in range(N)], np.float64).T
    got = run(device, module, "surface", lanes, buffer, 8).astype(np.float64)
    assert (got[:3][:, hit] == want[:3][:, hit]).all()
    assert (got[7][hit] == want[7][hit]).all()
    # float32 weights and normal: a few epsilons, more on the odd sliver whose weights cancel
    err = np.abs(got[3:7][:, hit] - want[3:7][:, hit]).max(axis=0)
    assert (err <= 1e-4).all() and (err <= 8 * np.finfo(F32).eps).mean() >= 0.99
    plane = np.array([PLAIN.normal(*buffer[:9, k]) for k in range(N)], np.float64).T
    blended = hit & (np.abs(np.abs(want[3:6]) - np.abs(plane)).max(axis=0) > 1e-3)
    assert blended[N // 4 :].sum() > N // 8 and not blended[: N // 4].any()


def test_builders_answers_are_the_pythons_bits(device, build_module):
    """triangle_build.wgsl's extent and leaf_row, as build.py assembles them:
    the Python's extent (three half sizes, padded) and copy_leaf (the nine
    vertex values, never the colour or the normals), bit for bit."""
    buffer = smooth(inputs(45)[0], np.random.default_rng(45))
    rows = {1: compute.triangle_rows(buffer)}
    got = dispatch(device, build_module, "extent", rows, 6, N)
    want = np.array([PLAIN.extent(buffer, k) for k in range(N)], F32).T
    assert (got.view(np.uint32) == want.view(np.uint32)).all()
    got = dispatch(device, build_module, "leaf_row", rows, 9, N)
    leaves = np.zeros((layout.TRI_ROWS, N), F32)
    for k in range(N):
        PLAIN.copy_leaf(buffer, k, leaves, k)
    assert (got.view(np.uint32) == leaves.view(np.uint32)).all()
