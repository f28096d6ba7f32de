"""The triangle primitive (kernels/primitives/triangle.py) against references
that share none of its code: a float64 NumPy solve of the ray-plane-barycentric
system for the hits, t and the cosine; closed meshes (trimesh's icosphere, a
cube) that every ray from inside must hit, on and off their shared edges and
vertices; triangles of zero area that no ray may hit; the padded boxes that
must hold each triangle and each hit point; and the answers that must agree
with each other (any hit and closest hit, a packet's and a ray's, the packed
leaf copy and the rows).

The watertight tests run the numba-compiled functions (numba.njit), which
round as the CPU's kernels do; the plain-Python build must give the very
same bits (test_plain_and_compiled_agree).
"""

from __future__ import annotations

import numba
import numpy as np
import pytest

from raybench.kernels.primitives import KINDS, triangle
from raybench.layout import PAD, TRI_NA, TRI_ROWS, TRI_SMOOTH_ROWS

trimesh = pytest.importorskip("trimesh")

F32 = np.float32
EPS = float(np.finfo(np.float32).eps)
PLAIN = triangle.make(lambda f: f)


@pytest.fixture(scope="module")
def jitted():
    """The compiled functions, and a brute-force closest hit over a buffer
    built from them: (prim, nearest(buffer, origins, directions) -> (hit, t))."""
    prim = triangle.make(numba.njit)
    hit = prim.hit

    @numba.njit
    def nearest(buffer, origins, directions):
        n = origins.shape[0]
        hits = np.full(n, -1, np.int32)
        ts = np.full(n, np.float32(3e38), np.float32)
        for r in range(n):
            ox, oy, oz = origins[r, 0], origins[r, 1], origins[r, 2]
            dx, dy, dz = directions[r, 0], directions[r, 1], directions[r, 2]
            for k in range(buffer.shape[1]):
                t, _ = hit(buffer, k, ox, oy, oz, dx, dy, dz)
                if t > 0 and t < ts[r]:
                    ts[r] = t
                    hits[r] = k
        return hits, ts

    return prim, nearest


def unit(v):
    """Rows of v as float32 unit vectors."""
    v = np.asarray(v, np.float64)
    return (v / np.linalg.norm(v, axis=-1, keepdims=True)).astype(F32)


def leaves(vertices, faces):
    """The scene's buffer of a mesh: (9, F) float32, A, B, C a column."""
    tri = np.asarray(vertices, F32)[np.asarray(faces)]
    return np.ascontiguousarray(tri.reshape(len(faces), 9).T)


def reference(buffer, o, d):
    """float64 answers for each (triangle k, ray k): solve o + t d = A +
    b (B - A) + c (C - A) for (t, b, c); returns t, the barycentrics
    (1 - b - c, b, c) and |n.d| / |n|."""
    b64 = buffer.astype(np.float64)
    a, bb, c = b64[0:3].T, b64[3:6].T, b64[6:9].T
    e1, e2 = bb - a, c - a
    o, d = o.astype(np.float64), d.astype(np.float64)
    m = np.stack([-d, e1, e2], axis=-1)
    x = np.linalg.solve(m, (o - a)[..., None])[..., 0]
    n = np.cross(e1, e2)
    cos = np.abs((n * d).sum(1)) / np.linalg.norm(n, axis=1)
    return x[:, 0], np.stack([1 - x[:, 1] - x[:, 2], x[:, 1], x[:, 2]], 1), cos


def random_pairs(rng, n):
    """n random triangles (one a column) and one ray each, aimed at a point
    of the triangle's plane near it (about half inside), from up to 10 away."""
    centre = rng.uniform(-5, 5, (n, 1, 3))
    verts = (centre + rng.uniform(-1, 1, (n, 3, 3)) * rng.uniform(0.01, 2, (n, 1, 1))).astype(F32)
    buffer = np.ascontiguousarray(verts.reshape(n, 9).T)
    w = rng.uniform(-0.3, 1.0, (n, 3))
    target = (w[:, :, None] * verts).sum(1) / w.sum(1, keepdims=True)
    o = (target + rng.normal(size=(n, 3)) * rng.uniform(0.5, 10, (n, 1))).astype(F32)
    return buffer, o, unit(target - o)


def test_registered_and_shaped():
    """One line in KINDS; the rows layout names; every answer the walks and
    the builders read, and none of the sphere's fast-kernel culls."""
    assert KINDS["triangle"] is triangle and triangle.LEAF_ROWS == TRI_ROWS == 9
    wanted = {"read", "read_leaf", "hit", "hit_ahead", "leaf_hit", "leaf_hit_ahead", "meets_own", "from_origin",
              "seen_from", "hit_from", "hit_ahead_from", "box_of", "bounds", "pad", "extent", "copy_leaf",
              "surface", "rim"}  # fmt: skip
    assert wanted <= set(vars(PLAIN))
    assert not {"prepare_at", "may_hit"} & set(vars(PLAIN))


def test_against_float64_reference(rng, jitted):
    """The same hits as the float64 solve, away from the edges (barycentrics
    over 1e-4) and from grazing (cos over 1e-3), with t within 4 float32
    epsilons of max |vertex - origin| / cos (the hit lies on the triangle of
    rounded sheared vertices: a few epsilons of their distance, along the
    ray over cos) plus one of t's own rounding; and the datum, |n.d|, within
    8 epsilons (n's three roundings to float32 and the float32 dot product's)."""
    prim, _ = jitted
    n = 4000
    buffer, o, d = random_pairs(rng, n)
    t_ref, bary, cos_ref = reference(buffer, o, d)
    got = np.array([prim.hit(buffer, k, *o[k], *d[k]) for k in range(n)], np.float64)
    inside = bary.min(1) > 1e-4
    outside = bary.min(1) < -1e-4
    clear = (cos_ref > 1e-3) & (inside | outside)
    hit_ref = inside & (t_ref > 0)
    hit = got[:, 0] > 0
    assert (hit[clear] == hit_ref[clear]).all(), np.flatnonzero(clear & (hit != hit_ref))[:5]
    assert hit_ref.sum() > n // 5 and (clear & ~hit_ref).sum() > n // 5  # both kinds well represented
    both = clear & hit_ref
    far = np.abs(buffer.T.reshape(n, 3, 3) - o[:, None, :]).max(axis=(1, 2))
    bound = 4 * EPS * far / cos_ref + EPS * t_ref
    assert (np.abs(got[both, 0] - t_ref[both]) <= bound[both]).all()
    assert (np.abs(got[both, 1] - cos_ref[both]) <= 8 * EPS).all()
    misses = got[~hit]
    assert (misses[:, 0] <= 0).all()


def test_plain_and_compiled_agree(rng, jitted):
    """The plain-Python build and numba's give the same bits, hits and misses."""
    prim, _ = jitted
    buffer, o, d = random_pairs(rng, 300)
    for k in range(300):
        a = PLAIN.hit(buffer, k, *o[k], *d[k])
        b = prim.hit(buffer, k, *o[k], *d[k])
        assert (F32(a[0]), F32(a[1])) == (F32(b[0]), F32(b[1])), k


def test_the_other_answers_agree(rng):
    """hit_ahead is hit's answer where the triangle is not the ray's own, and
    a miss where it is; a packet's hit_from(from_origin) and the packed leaf
    copy's leaf_hit give hit's very bits; copy_leaf copies nine rows; the
    walks never ask a triangle for its own (meets_own)."""
    buffer, o, d = random_pairs(rng, 200)
    packed = np.zeros((200, 2 * triangle.PACKED_WORDS), F32)
    packed[:, :9] = buffer.T
    packed = packed.view(np.float64)
    words = lambda w: tuple(np.array([w], np.float64).view(F32))  # noqa: E731
    prim_words = triangle.make(lambda f: f, words)
    copied = np.zeros((9, 200), F32)
    for k in range(200):
        args = (*o[k], *d[k])
        first = PLAIN.hit(buffer, k, *args)
        assert PLAIN.hit_ahead(buffer, k, *args, False) == first
        assert PLAIN.hit_ahead(buffer, k, *args, True)[0] <= 0
        assert PLAIN.hit_from(PLAIN.from_origin(buffer, k, *o[k]), *d[k]) == first
        assert PLAIN.hit_ahead_from(PLAIN.seen_from(PLAIN.read_leaf(buffer, k), *o[k]), *d[k], False) == first
        assert prim_words.read_leaf(packed, k) == PLAIN.read(buffer, k)
        assert prim_words.leaf_hit(packed, k, *args) == first
        PLAIN.copy_leaf(buffer, k, copied, k)
    assert (copied == buffer).all()
    assert not PLAIN.meets_own(True) and not PLAIN.meets_own(False)


def rays_at(origins, targets):
    """Rays from each origin aimed at each target (float32 unit directions)."""
    return np.asarray(origins, F32), unit(np.asarray(targets, np.float64) - np.asarray(origins, np.float64))


def edge_targets(mesh, rng, n):
    """Points a ray is aimed at: the mesh's vertices, its edges' midpoints,
    points along its edges, all in float32."""
    v = np.asarray(mesh.vertices, np.float64)
    e = np.asarray(mesh.edges_unique)
    pick = rng.integers(0, len(e), n)
    along = rng.uniform(0, 1, (n, 1))
    on_edges = v[e[pick, 0]] * (1 - along) + v[e[pick, 1]] * along
    return np.concatenate([v, v[e].mean(1), on_edges]).astype(F32)


@pytest.mark.parametrize("centre, radius", [((0, 0, 0), 1.0), ((1000, -2000, 500), 0.01)])
def test_watertight_icosphere(jitted, centre, radius):
    """Every ray from inside a subdivided icosphere hits it: random ones, and
    ones aimed at its vertices and along its shared edges, from random points
    inside and from the centre; at the origin, and small and far from it
    (where the float32 vertices are coarse against the sphere's size)."""
    prim, nearest = jitted
    rng = np.random.default_rng(37)
    mesh = trimesh.creation.icosphere(subdivisions=3, radius=radius)
    mesh.apply_translation(centre)
    buffer = leaves(mesh.vertices, mesh.faces)
    targets = edge_targets(mesh, rng, 2000)
    inside = rng.normal(size=(len(targets), 3))
    inside *= rng.uniform(0, 0.9 * radius, (len(targets), 1)) / np.linalg.norm(inside, axis=1, keepdims=True)
    inside += centre
    o1, d1 = rays_at(inside, targets)
    o2, d2 = rays_at(np.tile(np.float64(centre), (len(targets), 1)), targets)
    o3 = inside.astype(F32)
    d3 = unit(rng.normal(size=(len(targets), 3)))
    for o, d in ((o1, d1), (o2, d2), (o3, d3)):
        hits, ts = nearest(buffer, o, d)
        assert (hits >= 0).all(), f"{(hits < 0).sum()} of {len(hits)} rays slipped through"
        assert (ts < 2.1 * radius).all()


def test_watertight_cube(jitted):
    """A cube of 12 triangles with shared edges and diagonals: rays from
    inside aimed exactly at its corners, at points on its edges and on its
    faces' diagonals (some exactly representable, so the ray meets the edge
    at the very float32 point), all hit it."""
    prim, nearest = jitted
    rng = np.random.default_rng(38)
    mesh = trimesh.creation.box(extents=(1.0, 1.0, 1.0))
    buffer = leaves(mesh.vertices, mesh.faces)
    targets = edge_targets(mesh, rng, 3000)
    exact = np.array([[0.5, 0.5, 0.5], [-0.5, 0.5, 0.5], [0.5, 0.5, 0], [0.5, 0, 0.5], [0, 0.5, 0.5],
                      [0.5, 0.25, 0.25], [0.5, -0.25, 0.25], [0.25, 0.5, 0.25], [0.5, 0.125, -0.125]])  # fmt: skip
    corners = np.array(mesh.vertices)
    starts = [np.zeros((len(exact), 3)), np.full((len(exact), 3), 0.25), -np.full((len(exact), 3), 0.125)]
    for start in starts:
        for sign in corners[:, None, :] * 2:  # the exact targets turned to every octant
            o, d = rays_at(start, exact * sign)
            hits, _ = nearest(buffer, o, d)
            assert (hits >= 0).all(), (start[0], sign)
    inside = rng.uniform(-0.45, 0.45, (len(targets), 3))
    for o, d in (rays_at(inside, targets), rays_at(np.zeros_like(inside), targets)):
        hits, _ = nearest(buffer, o, d)
        assert (hits >= 0).all(), f"{(hits < 0).sum()} of {len(hits)} rays slipped through"


def test_degenerate_never_hit(jitted):
    """Triangles of zero area (a repeated vertex, three points on a line, one
    point) are never hit, whatever the ray: aimed at their points, along
    their line, from anywhere."""
    prim, nearest = jitted
    rng = np.random.default_rng(39)
    degenerate = np.array([
        [[0, 0, 0], [1, 1, 1], [2, 2, 2]],
        [[0, 0, 0], [1, 1, 1], [1, 1, 1]],
        [[1, 2, 3], [1, 2, 3], [1, 2, 3]],
        [[0, 0, 1], [0, 0, 2], [0, 0, 3]],
        [[-1, 0, 0], [0, 0, 0], [3, 0, 0]],
        [[0.5, 0.5, 0], [0.5, 0.5, 0], [0, 1, 0]],
    ], F32)  # fmt: skip
    buffer = np.ascontiguousarray(degenerate.reshape(-1, 9).T)
    points = degenerate.reshape(-1, 3).astype(np.float64)
    targets = np.concatenate([points, (points[0::3] + points[1::3]) / 2, points + 1e-3])
    for origin in rng.normal(size=(60, 3)) * 4:
        o, d = rays_at(np.repeat(origin[None], len(targets), 0), targets)
        hits, _ = nearest(buffer, o, d)
        assert (hits < 0).all()
    # along their own line, and from one of their points
    o, d = rays_at(points[0::3], points[2::3] + 1)
    assert (nearest(buffer, o, d)[0] < 0).all()
    o, d = rays_at(points[0::3] - 1, points[2::3])
    assert (nearest(buffer, o, d)[0] < 0).all()


def test_boxes_hold_triangle_pad_and_hits(rng):
    """box_of (the walks' leaf cull) and extent (the builders') hold each
    triangle grown by its pad, and the float32 point of every hit, grazing
    ones included (the padding's claim, triangle.py's docstring); centres
    are extent's centres to the bit; extent's three half sizes are the
    box's, not one cube's."""
    buffer, o, d = random_pairs(rng, 1500)
    tri = buffer.T.reshape(-1, 3, 3).astype(np.float64)
    lo, hi = tri.min(1), tri.max(1)
    centre, half = (lo + hi) / 2, (hi - lo) / 2
    pads = ((np.abs(centre).sum(1) + half.sum(1)) * float(PAD))[:, None]
    boxes = np.array([PLAIN.box_of(PLAIN.read_leaf(buffer, k)) for k in range(buffer.shape[1])], np.float64)
    ext = np.array([PLAIN.extent(buffer, k) for k in range(buffer.shape[1])], np.float64)
    assert (boxes[:, :3] <= lo - pads * 0.99).all() and (boxes[:, 3:] >= hi + pads * 0.99).all()
    assert (ext[:, :3] - ext[:, 3:] <= lo - pads * 0.99).all() and (ext[:, :3] + ext[:, 3:] >= hi + pads * 0.99).all()
    assert (ext[:, :3] == triangle.centres(buffer).T).all()
    assert (np.array([PLAIN.bounds(buffer, k) for k in range(5)]) == boxes[:5]).all()
    flat = np.abs(ext[:, 3:].max(1) / ext[:, 3:].min(1))
    assert (flat > 1.5).mean() > 0.3  # the half sizes differ: no cube
    # grazing rays: directions within the triangle's plane but for a little
    normal = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    normal /= np.linalg.norm(normal, axis=1, keepdims=True)
    slant = d - (d * normal).sum(1, keepdims=True) * normal * rng.uniform(0.99, 1.0, (len(d), 1))
    for dirs in (d, unit(slant)):
        for k in range(len(dirs)):
            t, _ = PLAIN.hit(buffer, k, *o[k], *dirs[k])
            if t > 0:
                p = o[k].astype(np.float64) + float(t) * dirs[k].astype(np.float64)
                margin = np.abs(o[k]).sum() * float(PAD)  # what the walks add for the origin
                assert (p >= boxes[k, :3] - margin).all() and (p <= boxes[k, 3:] + margin).all(), k


def test_surface_flat_and_smooth():
    """surface: the plane's unit normal turned to the ray, the back face said
    (inside); with corner normals (TRI_SMOOTH_ROWS), their barycentric blend:
    a corner's own at that corner, the blend between, never facing away."""
    tri = np.array([[-1, -1, 5], [1, -1, 5], [0, 1, 5]], F32)  # counter-clockwise from +z: normal +z
    flat = np.ascontiguousarray(tri.reshape(1, 9).T)
    z = F32(0)
    front = PLAIN.surface(z, z, F32(10), z, z, F32(-1), F32(5), 0, flat)
    assert front[3:] == (0, 0, 1, 1, False)
    back = PLAIN.surface(z, z, z, z, z, F32(1), F32(5), 0, flat)
    assert back[3:] == (0, 0, -1, 1, True) and back[:3] == (0, 0, 5)
    corners = unit([[0.3, 0, 1], [0, 0.3, 1], [-0.3, -0.3, 1]])
    smooth = np.zeros((TRI_SMOOTH_ROWS, 1), F32)
    smooth[:9, 0] = tri.reshape(9)
    smooth[TRI_NA:, 0] = corners.reshape(9)
    for v, n in zip(tri, corners):
        o = (v + F32([0, 0, 10])).astype(F32)
        *_, nx, ny, nz, cos_i, inside = PLAIN.surface(*o, z, z, F32(-1), F32(10), 0, smooth)
        assert np.allclose((nx, ny, nz), n, atol=1e-6) and not inside and cos_i > 0
    # from behind, the same normals turned to the ray
    *_, nx, ny, nz, cos_i, inside = PLAIN.surface(z, z, z, z, z, F32(1), F32(5), 0, smooth)
    blend = unit(corners.astype(np.float64).T @ reference(smooth[:9], np.zeros((1, 3)), np.float32([[0, 0, 1]]))[1][0])
    assert inside and np.allclose((nx, ny, nz), -blend, atol=1e-6) and cos_i > 0
    assert PLAIN.rim(smooth, 0) == 1


def test_every_answer_compiles(rng, jitted):
    """Every answer compiles with numba.njit (as the backends will compile
    them) and gives the plain build's values: the boxes, the packet's test,
    the leaf copy, and the surface, flat and smooth."""
    prim, _ = jitted
    buffer, o, d = random_pairs(rng, 50)
    colours = rng.uniform(0, 1, (3, 50)).astype(F32)
    normals = np.repeat(unit(rng.normal(size=(1, 9)).reshape(3, 3)).reshape(9, 1), 50, 1)
    smooth = np.concatenate([buffer, colours, normals]).astype(F32)
    assert smooth.shape[0] == TRI_SMOOTH_ROWS
    copies = np.zeros((9, 50), F32), np.zeros((9, 50), F32)
    for k in range(50):
        args = (*o[k], *d[k])
        assert prim.extent(buffer, k) == PLAIN.extent(buffer, k)
        assert prim.bounds(buffer, k) == PLAIN.bounds(buffer, k)
        seen = tuple(map(F32, prim.from_origin(buffer, k, *o[k])))  # float32 again, as compiled callers keep it
        assert prim.hit_ahead_from(seen, *d[k], False) == PLAIN.hit(buffer, k, *args)
        assert prim.leaf_hit_ahead(buffer, k, *args, False) == PLAIN.hit(buffer, k, *args)
        prim.copy_leaf(buffer, k, copies[0], k)
        PLAIN.copy_leaf(buffer, k, copies[1], k)
        t, _ = PLAIN.hit(buffer, k, *args)
        if t > 0:
            for scene in (buffer, smooth):
                assert prim.surface(*args, t, k, scene) == PLAIN.surface(*args, t, k, scene)
    assert (copies[0] == copies[1]).all() and (copies[0] == buffer).all()
    assert prim.rim(buffer, 0) == 1 and not prim.meets_own(True)
    assert all(prim.colour(smooth, k) == tuple(colours[:, k]) for k in range(50))


def test_the_program_compiles_for_the_triangle(rng):
    """kernels.make takes the triangle as it takes the sphere (the seam):
    its brute-force search over a mesh's triangles gives, for every ray, the
    triangle of the smallest positive t in the float64 reference, and the
    fast kernels' cull, which a triangle has not, is left out."""
    from raybench import kernels

    program = kernels.make(lambda f: f, primitive=triangle)
    assert program.prepare is None
    n = 24
    buffer, o, d = random_pairs(rng, n)
    far = np.float32(3e38)
    judged = 0
    for k in range(n):
        hit, t, _cos = program.scan(*o[k], *d[k], far, False, False, -1, False, buffer, n)
        ts, bary, _ = reference(buffer, np.repeat(o[k : k + 1], n, 0), np.repeat(d[k : k + 1], n, 0))
        inside = (bary > 1e-4).all(1) & (ts > 1e-4)
        if not inside.any():
            continue  # only rays that meet some triangle clearly inside it are judged
        best = int(np.argmin(np.where(inside, ts, np.inf)))
        grazing = (np.abs(bary) < 1e-4).any(1) & (ts > 0)  # a near-edge rival could win on rounding
        if not grazing.any():
            assert hit == best and abs(t - ts[best]) <= 1e-4 * max(1.0, ts[best]), (k, hit, best)
            judged += 1
    assert judged >= n // 4, judged
