"""Each WGSL function against its Python twin, function by function: the
sphere (kernels/primitives/sphere.py, sphere.wgsl), the walk's slab test and
its set-up (kernels/traverse.py, traverse.wgsl), the thesis's shading
(kernels/shade.py, shade.wgsl). The frame tests (test_wgpu.py) see a WGSL
function only through the pixels it changes; here each runs on its own, on
random float32 inputs and on the edges (misses, tangent rays, an origin
inside or at the centre, far_only, zero direction components, the empty
child's inverted box), and must give its twin's very bits. The triangle's
twins (triangle.wgsl, triangle_box.wgsl, triangle_build.wgsl: the tests,
surface, the boxes, extent and leaf_row) are held to theirs in
test_triangle_wgsl.py, within stated ulps where the Python works in float64.

The WGSL is the real shader (shader.source: the pieces as the tracer
assembles them), with one small entry point a function appended, which reads
each lane's arguments from a buffer and writes its results to another. The
Python runs as plain Python (build(PLAIN)): every operation on numpy float32,
rounded as WGSL's f32 rounds it.

Bit for bit on a CPU adapter (lavapipe, CI's): it rounds every operation to
float32 and fuses nothing, as the CPU's compiled kernels do (test_wgpu.py
finds their frames the same bytes). A GPU compiler may fuse a product into a
sum, and WGSL lets its division be off by 2.5 ulp, which moves a result by an
ulp of its terms and, near a branch's edge (a tangent ray's disc), flips the
branch: no stated ulp count bounds that, so this test wants a CPU adapter and
skips where there are only GPUs (the frame tests hold a GPU to the CPU within
a colour step there). Where wgpu finds no adapter at all it skips, or fails
under RAYBENCH_REQUIRE_WGPU=1 (conftest's adapter fixture).
"""

from __future__ import annotations

import inspect

import numpy as np
import pytest
from wgsl_harness import IN, cpu_adapter, dispatch, entry_points

from raybench import layout
from raybench.backends.wgpu import adapters, compute, shader
from raybench.kernels import shade, traverse
from raybench.kernels.primitives import sphere

pytestmark = pytest.mark.gpu

PLAIN = lambda f: f  # noqa: E731 - build(PLAIN): the kernels as plain Python
F32 = np.float32


def python_twins():
    """The Python functions, by their WGSL twin's name."""
    prim = sphere.make(PLAIN)
    walks = traverse.make(PLAIN, prim)
    inverse, ray_axes, children = walks.inverse, walks.ray_axes, walks.children
    shade_hit = shade.make(PLAIN)[0]
    return {
        "prim": prim,
        "inverse": inverse,
        "ray_axes": ray_axes,
        # the walk's own slab and axis_setup, as children and ray_axes call them
        "slab": inspect.getclosurevars(children).nonlocals["slab"],
        "axis_setup": inspect.getclosurevars(ray_axes).nonlocals["axis_setup"],
        "shade_hit": shade_hit,
    }


PY = python_twins()
P = PY["prim"]


def args(k, n):
    """WGSL text: the lane's arguments k to k + n - 1, comma-separated."""
    return ", ".join(f"arg({j}u, i)" for j in range(k, k + n))


def vec3(k):
    return f"vec3<f32>({args(k, 3)})"


def puts(*values):
    return " ".join(f"put({j}u, i, {v});" for j, v in enumerate(values))


# name: (WGSL body, the bindings it reads beside its own, Python twin of one lane:
# (lane's arguments as float32, spheres (7, N), ordered (4, N), lane) -> results)
CASES = {
    "along": (
        f"put(0u, i, along({args(0, 6)}));",
        (),
        lambda a, s, o, k: P.along(*a[:6]),
    ),
    "chord": (
        f"let r = chord({args(0, 7)}); {puts('r.x', 'r.y')}",
        (),
        lambda a, s, o, k: P.chord(*a[:7]),
    ),
    "intersect_relative": (
        f"let r = intersect_relative({args(0, 7)}); {puts('r.x', 'r.y')}",
        (),
        lambda a, s, o, k: P.intersect_relative(*a[:7]),
    ),
    "intersect_ahead": (
        f"let r = intersect_ahead({args(0, 7)}, arg(7u, i) != 0.0); {puts('r.x', 'r.y')}",
        (),
        lambda a, s, o, k: P.intersect_ahead(*a[:7], bool(a[7])),
    ),
    "intersect": (
        f"let r = intersect({vec3(0)}, {vec3(3)}, vec4<f32>({args(6, 4)})); {puts('r.x', 'r.y')}",
        (),
        lambda a, s, o, k: P.intersect(*a[:10]),
    ),
    "read_sphere": (
        f"let c = read_sphere(k); {puts('c.x', 'c.y', 'c.z', 'c.w')}",
        ("spheres",),
        lambda a, s, o, k: P.read(s, k),
    ),
    "read_leaf": (
        f"let c = read_leaf(k); {puts('c.x', 'c.y', 'c.z', 'c.w')}",
        ("ordered",),
        lambda a, s, o, k: P.read_leaf(o, k),
    ),
    "hit": (
        f"let r = hit(k, {vec3(0)}, {vec3(3)}); {puts('r.x', 'r.y')}",
        ("spheres",),
        lambda a, s, o, k: P.hit(s, k, *a[:6]),
    ),
    "hit_ahead": (
        f"let r = hit_ahead(k, {vec3(0)}, {vec3(3)}, arg(6u, i) != 0.0); {puts('r.x', 'r.y')}",
        ("spheres",),
        lambda a, s, o, k: P.hit_ahead(s, k, *a[:6], bool(a[6])),
    ),
    "leaf_hit": (
        f"let r = leaf_hit(k, {vec3(0)}, {vec3(3)}); {puts('r.x', 'r.y')}",
        ("ordered",),
        lambda a, s, o, k: P.leaf_hit(o, k, *a[:6]),
    ),
    "leaf_hit_ahead": (
        f"let r = leaf_hit_ahead(k, {vec3(0)}, {vec3(3)}, arg(6u, i) != 0.0); {puts('r.x', 'r.y')}",
        ("ordered",),
        lambda a, s, o, k: P.leaf_hit_ahead(o, k, *a[:6], bool(a[6])),
    ),
    "from_origin": (
        f"let c = from_origin(k, {vec3(0)}); {puts('c.x', 'c.y', 'c.z', 'c.w')}",
        ("ordered",),
        lambda a, s, o, k: P.from_origin(o, k, *a[:3]),
    ),
    "hit_from": (
        f"let r = hit_from(vec4<f32>({args(0, 4)}), {vec3(4)}); {puts('r.x', 'r.y')}",
        (),
        lambda a, s, o, k: P.hit_from(tuple(a[:4]), *a[4:7]),
    ),
    "hit_ahead_from": (
        f"let r = hit_ahead_from(vec4<f32>({args(0, 4)}), {vec3(4)}, arg(7u, i) != 0.0); {puts('r.x', 'r.y')}",
        (),
        lambda a, s, o, k: P.hit_ahead_from(tuple(a[:4]), *a[4:7], bool(a[7])),
    ),
    "meets_own": (
        "put(0u, i, flag(meets_own(arg(0u, i) != 0.0)));",
        (),
        lambda a, s, o, k: P.meets_own(bool(a[0])),
    ),
    "surface": (
        f"let h = surface({vec3(0)}, {vec3(3)}, arg(6u, i), k); "
        + puts("h.p.x", "h.p.y", "h.p.z", "h.n.x", "h.n.y", "h.n.z", "h.cos_i", "flag(h.inside)"),
        ("spheres",),
        lambda a, s, o, k: P.surface(*a[:7], k, s),
    ),
    "rim": (
        "put(0u, i, rim(k));",
        ("spheres",),
        lambda a, s, o, k: P.rim(s, k),
    ),
    "inverse": (
        "put(0u, i, inverse(arg(0u, i)));",
        (),
        lambda a, s, o, k: PY["inverse"](a[0]),
    ),
    "axis_setup": (
        f"let x = axis_setup({args(0, 3)}); {puts('x.inv', 'x.lo', 'x.hi')}",
        (),
        lambda a, s, o, k: PY["axis_setup"](*a[:3]),
    ),
    "ray_axes": (
        f"let x = ray_axes({vec3(0)}, {vec3(3)}); "
        + puts("x.x.inv", "x.y.inv", "x.z.inv", "x.x.lo", "x.y.lo", "x.z.lo", "x.x.hi", "x.y.hi", "x.z.hi"),
        (),
        lambda a, s, o, k: PY["ray_axes"](*a[:6]),
    ),
    "slab": (
        f"let r = slab({vec3(0)}, {vec3(3)}, Axis(arg(6u, i), arg(9u, i), arg(12u, i)), "
        "Axis(arg(7u, i), arg(10u, i), arg(13u, i)), Axis(arg(8u, i), arg(11u, i), arg(14u, i))); "
        + puts("r.x", "r.y"),
        (),
        lambda a, s, o, k: PY["slab"](*a[:15]),
    ),
    "shade_hit": (
        f"let c = shade_hit({args(0, 5)}); {puts('c.x', 'c.y', 'c.z')}",
        (),
        lambda a, s, o, k: PY["shade_hit"](*a[:5]),
    ),
}


@pytest.fixture(scope="module")
def gpu(adapter):
    return adapters.request_device(cpu_adapter())


def wgsl_source(count):
    """The tracer's whole shader (both walks' functions, the sphere, the
    shading) and an entry point a case."""
    text = shader.source((1, 1), "bvh", "ray")
    return text + entry_points({name: body for name, (body, _uses, _twin) in CASES.items()}, count)


def run_wgsl(device, module, name, lanes, spheres, ordered, results):
    """The WGSL function `name` on each lane's arguments (lanes: (n_args,
    N) float32): its results, (results, N) float32."""
    body, uses, _twin = CASES[name]
    given = {
        "in": (IN, np.ascontiguousarray(lanes, F32)),
        "spheres": (1, compute.sphere_rows(spheres)),
        "ordered": (5, np.ascontiguousarray(ordered.T)),
    }
    bound = dict(given[use] for use in uses + (("in",) if "arg(" in body else ()))
    return dispatch(device, module, name, bound, results, lanes.shape[1])


def run_python(name, lanes, spheres, ordered):
    """The Python twin on each lane: (results, N) float32 (a bool as 0 or 1)."""
    twin = CASES[name][2]
    rows = []
    for k in range(lanes.shape[1]):
        got = twin([F32(v) for v in lanes[:, k]], spheres, ordered, k)
        rows.append([F32(v) for v in (got if isinstance(got, tuple) else (got,))])
    return np.array(rows, F32).T


def unit(v):
    """Rows of (3, N) made unit as the primary rays are, in float32 (trace.primary_ray)."""
    v = v.astype(F32)
    inv = F32(1.0) / np.sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2])
    return v * inv


def directions(rng, n):
    """Unit rays, a quarter of them with zero components (axis-aligned, or in a plane)."""
    d = unit(rng.normal(size=(3, n)))
    q = n // 4
    axes = np.zeros((3, q), F32)
    axes[rng.integers(0, 3, q), np.arange(q)] = rng.choice(F32([-1.0, 1.0]), q)
    d[:, :q] = axes
    planar = rng.normal(size=(3, q))
    planar[rng.integers(0, 3, q), np.arange(q)] = 0.0
    d[:, q : 2 * q] = unit(planar)
    return d


def sphere_rays(rng, n):
    """(EO (3, N), r (N,), d (3, N)): rays aimed near spheres, so that about half
    hit; the ray's origin inside some, at the centre of some, on the surface
    of some; small far ones; and tangent rays, whose disc is exactly 0 (an
    axis-aligned ray and a sphere whose centre is r off its line along
    another axis)."""
    d = directions(rng, n)
    r = (10.0 ** rng.uniform(-2, 1.5, n)).astype(F32)
    v = rng.uniform(-40, 40, n)
    off = unit(np.cross(d.T, rng.normal(size=(n, 3))).T) * (r * rng.uniform(0, 1.3, n))
    e = (v * d + off).astype(F32)
    far = slice(0, n // 8)  # small, far spheres: the discriminant's digits
    e[:, far] *= F32(300.0)
    inside = slice(n // 8, n // 4)  # the origin inside
    e[:, inside] = (unit(rng.normal(size=(3, n // 8))) * (r[inside] * rng.uniform(0, 0.99, n // 8))).astype(F32)
    e[:, n // 4 : n // 4 + 8] = 0.0  # the origin at the centre
    t = slice(n // 4 + 8, n // 4 + 8 + n // 8)  # tangent
    m = n // 8
    axis = rng.integers(0, 3, m)
    d[:, t] = 0.0
    d[axis, np.arange(n // 4 + 8, n // 4 + 8 + m)] = rng.choice(F32([-1.0, 1.0]), m)
    e[:, t] = 0.0
    e[axis, np.arange(n // 4 + 8, n // 4 + 8 + m)] = rng.uniform(-40, 40, m)
    side = (axis + 1) % 3
    e[side, np.arange(n // 4 + 8, n // 4 + 8 + m)] = r[t] * rng.choice([-1.0, 1.0], m)
    # the origin on the surface (a secondary ray leaving its sphere), going in
    # or out along an axis: a root at exactly t = 0
    s = np.arange(n // 4 + 8 + m, n // 4 + 8 + m + n // 16)
    d[:, s] = 0.0
    d[rng.integers(0, 3, s.size), s] = rng.choice(F32([-1.0, 1.0]), s.size)
    e[:, s] = d[:, s] * r[s] * rng.choice(F32([-1.0, 1.0]), s.size)
    return e, r, d


def scene_of(e, r, rng):
    """Spheres (7, N) whose centres are origin + EO for random origins: (spheres, origins)."""
    n = r.shape[0]
    o = rng.uniform(-100, 100, (3, n)).astype(F32)
    spheres = np.zeros((7, n), F32)
    spheres[:3] = o + e
    spheres[3] = r
    spheres[4:] = rng.uniform(0, 1, (3, n))
    return spheres, o


def lanes_for(name, rng, n):
    """(lanes (n_args, N), spheres (7, N), ordered (4, N)) for one case."""
    e, r, d = sphere_rays(rng, n)
    spheres, o = scene_of(e, r, rng)
    ordered = spheres[:4][:, rng.permutation(n)].copy()
    far_only = rng.integers(0, 2, n).astype(F32)
    if name in ("along", "chord", "intersect_relative", "intersect_ahead", "hit_from", "hit_ahead_from"):
        return np.vstack([e, r, d, far_only]), spheres, ordered
    if name == "intersect":
        return np.vstack([o, d, spheres[:4]]), spheres, ordered
    if name in ("hit", "hit_ahead", "read_sphere", "rim"):
        # the origin and EO as the Python takes them: rounded from the sphere's centre
        return np.vstack([o, d, far_only]), spheres, ordered
    if name in ("leaf_hit", "leaf_hit_ahead", "read_leaf", "from_origin"):
        origin = (ordered[:3] - e).astype(F32)
        return np.vstack([origin, d, far_only]), spheres, ordered
    if name == "meets_own":
        return far_only[None], spheres, ordered
    if name == "surface":
        # t at the near or far root (or past the sphere: any point but the centre)
        v = np.einsum("ij,ij->j", e, d)
        half = np.sqrt(np.maximum(r * r - np.einsum("ij,ij->j", e - v * d, e - v * d), 0))
        t = (v + rng.choice([-1.0, 1.0], n) * half + rng.normal(0, 0.01, n) * r).astype(F32)
        return np.vstack([o, d, t]), spheres, ordered
    if name == "inverse":
        edges = F32([0.0, -0.0, 1e-20, -1e-20, 1e-21, -1e-21, 1e-19, -1e-19, 1.0, -1.0, 1e-30, -1e-30])
        return np.concatenate([edges, d.ravel()[: n - edges.size]])[None], spheres, ordered
    o = rng.uniform(-1000, 1000, (3, n)).astype(F32)
    if name == "ray_axes":
        return np.vstack([o, d]), spheres, ordered
    margin = ((np.abs(o[0]) + np.abs(o[1])) + np.abs(o[2])) * layout.PAD
    if name == "axis_setup":
        return np.vstack([o[0], d[0], margin]), spheres, ordered
    if name == "slab":
        axes = np.array([PY["ray_axes"](*(F32(x) for x in lane)) for lane in np.vstack([o, d]).T], F32).T
        centre = rng.uniform(-1000, 1000, (3, n)).astype(F32)
        size = (10.0 ** rng.uniform(-3, 3, (3, n))).astype(F32)
        lo, hi = centre - size, centre + size
        lo[:, : n // 16] = layout.EMPTY  # the empty child's inverted box
        hi[:, : n // 16] = -layout.EMPTY
        return np.vstack([lo, hi, axes]), spheres, ordered
    assert name == "shade_hit"
    colour = rng.uniform(0, 1, (3, n)).astype(F32)
    return np.vstack([colour, r, (r * rng.uniform(0, 1, n)).astype(F32)]), spheres, ordered


N = 2048


@pytest.fixture(scope="module")
def module(gpu):
    return gpu.create_shader_module(code=wgsl_source(N))


@pytest.mark.parametrize("name", sorted(CASES))
def test_wgsl_function_gives_its_python_twins_bits(gpu, module, rng, name):
    lanes, spheres, ordered = lanes_for(name, rng, N)
    want = run_python(name, lanes, spheres, ordered)
    got = run_wgsl(gpu, module, name, lanes, spheres, ordered, want.shape[0])
    same = got.view(np.uint32) == want.view(np.uint32)
    if cpu_adapter().backend == "OpenGL":
        # llvmpipe through OpenGL (a machine without Vulkan) negates a zero into +0 where the
        # twin gives -0 (a grazing ray's cosine, -(+0)): there a zero's sign is let go; on
        # Vulkan (lavapipe, CI's) every bit is held
        same |= (got == 0) & (want == 0)
    differ = np.flatnonzero((~same).any(axis=0))
    shown = [
        f"lane {k}: args {lanes[:, k].tolist()} -> wgsl {got[:, k].tolist()}, python {want[:, k].tolist()}"
        for k in differ[:4]
    ]
    assert differ.size == 0, f"{name}: {differ.size} of {N} lanes differ in their bits\n" + "\n".join(shown)


def test_the_cases_reach_the_edges(rng):
    """The inputs do what they claim: hits and misses, tangent rays (disc
    exactly 0), origins inside and on the surface, far_only both ways, zero
    direction components, empty boxes; else a test above could pass on easy
    inputs."""
    lanes, _s, _o = lanes_for("intersect_ahead", rng, N)
    e, r, d, far_only = lanes[:3], lanes[3], lanes[4:7], lanes[7]
    disc = np.array([P.chord(*(F32(x) for x in lanes[:7, k]))[1] for k in range(N)], F32)
    assert (disc > 0).sum() > N // 4 and (disc < 0).sum() > N // 8 and (disc == 0).sum() > N // 16
    near = np.array([P.intersect_relative(*(F32(x) for x in lanes[:7, k]))[0] for k in range(N)], F32)
    assert (near == 0).sum() > N // 64  # the origin on the surface, going in
    assert (np.einsum("ij,ij->j", e, e) < r * r).sum() > N // 16
    assert 0 < far_only.sum() < N and (d == 0).any(axis=0).sum() > N // 4
    inverse = lanes_for("inverse", rng, N)[0][0]
    assert (inverse == 0).sum() >= 2 and np.signbit(inverse[inverse == 0]).any()
    assert (lanes_for("slab", rng, N)[0][0] == layout.EMPTY).sum() == N // 16
