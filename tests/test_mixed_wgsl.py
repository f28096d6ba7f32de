"""mixed.wgsl against the sphere's and the triangle's own shaders, answer by
answer, on a CPU adapter (lavapipe), in the manner of test_triangle_wgsl.py:
each answer on a primitive of a buffer of both kinds is, bit for bit, the
kind's own answer (sphere.wgsl's, triangle.wgsl's, each assembled as its
kind's shader is) on that kind's own buffer, as test_mixed holds mixed.py's
answers to sphere.py's and triangle.py's. So the tag, the readers of the
mixed rows and leaves, and the one Seen of either kind are held; the tests
of the kinds' pieces (test_wgsl_parity.py, test_triangle_wgsl.py) hold the
arithmetic they call. And mixed_build.wgsl, as build.py assembles it: the
Python's extent and copy_leaf (kernels/primitives/mixed.py), bit for bit.
"""

from __future__ import annotations

import re

import numpy as np
import pytest
from wgsl_harness import IN, cpu_adapter, dispatch, entry_points

from raybench import layout
from raybench.backends.wgpu import adapters, compute, namespace, shader
from raybench.backends.wgpu import build as gpu_build
from raybench.kernels.primitives import mixed
from raybench.scene_meshes import mixed_leaves

pytestmark = pytest.mark.gpu

F32 = np.float32
PLAIN = mixed.make(lambda f: f)
SPHERES, TRIANGLES = 300, 300
# name: (WGSL body, its results); the lane's ray is o (0-2) and d (3-5), t (6); primitive k is lane k's
CASES = {
    "hit": ("let r = hit(k, v3(0u, i), v3(3u, i)); let s = hit_ahead(k, v3(0u, i), v3(3u, i), false);"
            " let q = hit_ahead(k, v3(0u, i), v3(3u, i), true); put(0u, i, r.x); put(1u, i, r.y);"
            " put(2u, i, s.x); put(3u, i, s.y); put(4u, i, q.x); put(5u, i, q.y);", 6),
    "leaf_hit": ("let r = leaf_hit(k, v3(0u, i), v3(3u, i)); let s = leaf_hit_ahead(k, v3(0u, i), v3(3u, i), false);"
                 " let q = leaf_hit_ahead(k, v3(0u, i), v3(3u, i), true); put(0u, i, r.x); put(1u, i, r.y);"
                 " put(2u, i, s.x); put(3u, i, s.y); put(4u, i, q.x); put(5u, i, q.y);", 6),
    "hit_from": ("let seen = from_origin(k, v3(0u, i)); let r = hit_from(seen, v3(3u, i));"
                 " let s = hit_ahead_from(seen, v3(3u, i), false); let q = hit_ahead_from(seen, v3(3u, i), true);"
                 " put(0u, i, r.x); put(1u, i, r.y); put(2u, i, s.x); put(3u, i, s.y); put(4u, i, q.x);"
                 " put(5u, i, q.y);", 6),
    "surface": ("let h = surface(v3(0u, i), v3(3u, i), arg(6u, i), k); put(0u, i, h.p.x); put(1u, i, h.p.y);"
                " put(2u, i, h.p.z); put(3u, i, h.n.x); put(4u, i, h.n.y); put(5u, i, h.n.z); put(6u, i, h.cos_i);"
                " put(7u, i, flag(h.inside)); put(8u, i, rim(k)); put(9u, i, spheres[k].red);"
                " put(10u, i, spheres[k].green); put(11u, i, spheres[k].blue);", 12),
}  # fmt: skip
# What each case binds: the scene's rows (1), the tree's leaves (5)
BINDS = {"hit": (1,), "leaf_hit": (5,), "hit_from": (5,), "surface": (1,)}
# common.wgsl's binding of the scene's buffer, which the pieces read as their struct Sphere
SCENE = "@group(0) @binding(1) var<storage, read> spheres: array<Sphere>;\n"


@pytest.fixture(scope="module")
def device(adapter):
    return adapters.request_device(cpu_adapter())


def module(device, primitive: str, lanes: int):
    """The kind's pieces as its shader takes them (shader.kind_piece), with
    the entry points for `lanes` lanes."""
    text = SCENE + "\n".join(shader.kind_piece(p, primitive) for p in shader.KIND_PIECES[primitive])
    for name, value in {**shader.BVH_CONSTANTS, **shader.MIXED_CONSTANTS}.items():
        text = text.replace(name, value)
    return device.create_shader_module(code=text + entry_points({n: body for n, (body, _) in CASES.items()}, lanes))


def unit(v):
    v = np.asarray(v, np.float64)
    return (v / np.linalg.norm(v, axis=-1, keepdims=True)).astype(F32)


def inputs(seed=51):
    """(spheres (7, S), triangles with colour and corners' normals (21, T),
    lanes (7, S + T)): each lane's ray aimed near its primitive (about half
    hit), from outside it and, for a few spheres, from inside; t of the
    lane's hit (or 1) for surface."""
    rng = np.random.default_rng(seed)
    spheres = np.zeros((layout.SPHERE_ROWS, SPHERES), F32)
    spheres[:3] = rng.uniform(-20, 20, (3, SPHERES))
    spheres[3] = rng.uniform(0.05, 3, SPHERES)
    spheres[4:7] = rng.uniform(0, 1, (3, SPHERES))
    triangles = np.zeros((layout.TRI_SMOOTH_ROWS, TRIANGLES), F32)
    centre = rng.uniform(-20, 20, (TRIANGLES, 1, 3))
    verts = centre + rng.uniform(-1, 1, (TRIANGLES, 3, 3)) * rng.uniform(0.1, 3, (TRIANGLES, 1, 1))
    triangles[: layout.TRI_ROWS] = verts.reshape(TRIANGLES, 9).T
    triangles[layout.TRI_RED : layout.TRI_RED + 3] = rng.uniform(0, 1, (3, TRIANGLES))
    triangles[layout.TRI_NA :] = unit(rng.normal(size=(TRIANGLES, 3, 3))).reshape(TRIANGLES, 9).T
    triangles[layout.TRI_NA :, : TRIANGLES // 4] = 0.0  # a quarter without corners' normals
    w = rng.uniform(-0.3, 1.0, (TRIANGLES, 3, 1))  # weights of the corners: inside the triangle where all >= 0
    aims = [spheres[:3].T + rng.normal(size=(SPHERES, 3)) * spheres[3, :, None], (w * verts).sum(1) / w.sum(1)]
    targets = np.concatenate(aims)
    o = targets + rng.normal(size=targets.shape) * rng.uniform(2, 30, (len(targets), 1))
    o[: SPHERES // 8] = spheres[:3, : SPHERES // 8].T  # from a sphere's centre: inside it
    d = unit(targets - o)
    lanes = np.concatenate([o, d, np.ones((len(o), 1))], axis=1).T.astype(F32)
    return spheres, triangles, np.ascontiguousarray(lanes)


def run(device, modules, primitive, name, rows, leaves, lanes):
    """Case `name` of the kind's module on each lane: (results, lanes) float32."""
    _body, results = CASES[name]
    count = lanes.shape[1]
    if (primitive, count) not in modules:
        modules[primitive, count] = module(device, primitive, count)
    given = {1: rows, 5: leaves}
    bound = {IN: np.ascontiguousarray(lanes), **{b: given[b] for b in BINDS[name]}}
    return dispatch(device, modules[primitive, count], name, bound, results, count)


def test_each_answer_is_the_kinds_own_bits(device):
    """hit, hit_ahead (the ray's own primitive and not), their leaf and
    packet (from_origin) forms, surface, rim and the colour the shading
    reads: on a primitive of the buffer of both kinds, the bits of its
    kind's own shader on its kind's own buffer."""
    modules = {}
    spheres, triangles, lanes = inputs()
    both = mixed_leaves(spheres, triangles)
    tree = np.zeros((layout.MIX_LEAF_ROWS, both.shape[1]), F32)
    for k in range(both.shape[1]):
        PLAIN.copy_leaf(both, k, tree, k)
    own = {
        "mixed": (compute.mixed_rows(both), np.ascontiguousarray(tree.T)),
        "sphere": (compute.sphere_rows(spheres), np.ascontiguousarray(spheres[:4].T)),
        "triangle": (compute.triangle_rows(triangles), np.ascontiguousarray(triangles[: layout.TRI_ROWS].T)),
    }
    hits = run(device, modules, "mixed", "hit", *own["mixed"], lanes)[0]
    lanes[6] = np.where(hits > 0, hits, 1)
    for name in CASES:
        got = run(device, modules, "mixed", name, *own["mixed"], lanes)
        alone = [run(device, modules, "sphere", name, *own["sphere"], lanes[:, :SPHERES]),
                 run(device, modules, "triangle", name, *own["triangle"], lanes[:, SPHERES:])]  # fmt: skip
        assert np.array_equal(got.view(np.uint32), np.concatenate(alone, axis=1).view(np.uint32)), name
    inside = lanes[:, : SPHERES // 8]
    assert (hits[:SPHERES] > 0).mean() > 0.3 and (hits[SPHERES:] > 0).mean() > 0.3  # both kinds are hit
    assert (run(device, modules, "mixed", "hit", *own["mixed"], inside)[4] > 0).all()  # the far root from inside


def test_builders_answers_are_the_pythons_bits(device):
    """mixed_build.wgsl's extent and leaf_row, as build.py assembles them
    (the sphere's and the triangle's build pieces under prefixes): the
    Python's extent (a sphere's cube, a triangle's three half sizes, padded)
    and copy_leaf (a kind's leaf rows, zeros after a sphere's, the tag)."""
    spheres, triangles, _ = inputs(52)
    both = mixed_leaves(spheres, triangles)
    n = both.shape[1]
    cases = {
        "extent": "let e = extent(u32(k)); put(0u, i, e.centre.x); put(1u, i, e.centre.y);"
        " put(2u, i, e.centre.z); put(3u, i, e.half_size.x); put(4u, i, e.half_size.y); put(5u, i, e.half_size.z);",
        "leaf_row": "let r = leaf_row(u32(k)); for (var j = 0u; j < 10u; j++) { put(j, i, r[j]); }",
    }
    code = gpu_build.source("build_tree.wgsl", "mixed") + entry_points(cases, n)
    build_module = device.create_shader_module(code=code)
    rows = {1: compute.mixed_rows(both)}
    got = dispatch(device, build_module, "extent", rows, 6, n)
    want = np.array([PLAIN.extent(both, k) for k in range(n)], F32).T
    assert np.array_equal(got.view(np.uint32), want.view(np.uint32))
    got = dispatch(device, build_module, "leaf_row", rows, layout.MIX_LEAF_ROWS, n)
    leaves = np.zeros((layout.MIX_LEAF_ROWS, n), F32)
    for k in range(n):
        PLAIN.copy_leaf(both, k, leaves, k)
    assert np.array_equal(got.view(np.uint32), leaves.view(np.uint32))


def test_a_pieces_names_are_renamed_and_nothing_else():
    """namespace.namespaced: a declaration and its uses renamed, not a member
    of the same name, a longer name or a comment; kept as it is, dropped
    with its comment and its uses left, replaced with its uses renamed; a
    name the piece does not declare, or code outside a declaration, refused."""
    piece = (
        "// a header\n\n"
        "struct Hit { hit: f32 }\n"
        "// reads the buffer\n"
        "fn read(k: i32) -> f32 {\n    return buffer[k];\n}\n"
        "@group(0) @binding(5) var<storage, read> buffer: array<f32>;\n"
        "fn hit(k: i32) -> Hit {  // hit's own comment\n"
        "    let hits = read(k);\n    return Hit(hits + Hit(1.0).hit);\n}\n"
    )
    got = namespace.namespaced(piece, "s_", kept=("Hit",), dropped=("buffer",), replaced=("read",))
    assert got == (
        "// a header\n\n"
        "struct Hit { hit: f32 }\n"
        "fn s_hit(k: i32) -> Hit {  // hit's own comment\n"
        "    let hits = s_read(k);\n    return Hit(hits + Hit(1.0).hit);\n}\n"
    )
    with pytest.raises(ValueError, match="not declared in the piece: nothing"):
        namespace.namespaced(piece, "s_", kept=("nothing",))
    with pytest.raises(ValueError, match="not a top-level declaration"):
        namespace.namespaced(piece + "let stray = 1;\n", "s_")
    assert namespace.members(piece, "Hit") == "hit: f32"
    with pytest.raises(ValueError, match="struct read: not declared"):
        namespace.members(piece, "read")


def test_the_mixed_row_is_a_facet_and_the_tag():
    """mixed.wgsl's struct Tagged, as the shader has it: triangle.wgsl's
    Facet's members, then the tag (compute.py's mixed rows)."""
    text = shader.source((8, 8), "bvh", "ray", "mixed")
    facet = namespace.members(shader.kind_piece("triangle.wgsl", "triangle"), "Facet")
    tagged = re.search(r"struct Tagged \{(.*?)\}", text, re.S)
    assert tagged is not None and tagged[1].split() == [*facet.split(), "tag:", "f32,"]
