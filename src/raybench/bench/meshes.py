"""The meshes suite: what a frame of triangles costs as their count grows, and what a GPU buys
over the CPU on them.

Two generated meshes, each at counts from about 10 thousand to about 10 million triangles:

- "icosphere": trimesh.creation.icosphere of radius 1 at subdivisions 5 to 9 (20 x 4^k
  triangles: 20,480 to 5,242,880), the triangle issue's own workload;
- "random": random_triangles(n, seed) below, at 10,000, 100,000, 1,000,000 and 10,000,000.

Both are seen as the triangle issue's targets set it: from (0, 0, -2) looking at (0, 0, 0),
the icosphere's centre, up +y, a 60 degree field of view, at 1680x1050 (QUICK_SIZE with
--quick). Every triangle is matte, of meshes.MESH_COLOUR. Each point is traced twice through
the BVH: the thesis's shading (primary rays: one a pixel, |N.D| times the colour) and Whitted's
to depth 5 with 4 shadow samples of one spherical light of radius 0.5 centred at (-2, 3, -3)
(benchmarks/archive/mesh_first_figures.py's light, given a size: a point light casts one
shadow ray a hit whatever the samples asked for). On matte triangles Whitted's frame casts the
primary rays and, from every hit, a shadow ray to each of the light's 4 sample points that it
faces: no mirror or glass, so no bounce; the kernels count every ray cast.

Its points are made in suites.py (_meshes), from the counts here; the runner times them as any
frame (runner.measure, the scene from mesh_scene), and records a point as skipped where its
frame is predicted past the cap (predicted_ms: the growth its series has shown) or where it
would not fit: on the host (HOST_TRIANGLE_BYTES a triangle, checked before the mesh is made)
or on the device (the tracer's own refusal, a line naming what it needs). Its section of the
report is report/meshes_section.py.
"""

from __future__ import annotations

import functools
import math

import numpy as np

ICOSPHERE_SUBDIVISIONS = (5, 6, 7, 8, 9)
RANDOM_COUNTS = (10_000, 100_000, 1_000_000, 10_000_000)
QUICK_ICOSPHERE_SUBDIVISIONS = (2, 3, 4)
QUICK_RANDOM_COUNTS = (320, 1280, 5120)
SIZE = (1680, 1050)
QUICK_SIZE = (160, 100)
KINDS = ("icosphere", "random")
DEPTH = 5
SHADOW_SAMPLES = 4
EYE = (0.0, 0.0, -2.0)
LIGHT = (-2.0, 3.0, -3.0)
LIGHT_RADIUS = 0.5
# A frame predicted past this is recorded as skipped: a 2-vCPU CPU's Whitted frames of the
# largest meshes; a point times at least 5 frames (the first, warm-up, MIN_FRAMES).
CAP_S = 20.0
QUICK_CAP_S = 2.0
# The random triangles' corners spread RANDOM_EDGE * sqrt(RANDOM_REFERENCE / n) about each
# centre: the triangles' total area is the same at every count, so a ray crosses about as
# many of them whatever n, and the share of rays that hit one stays put: the count grows, not
# the coverage (docs/thesis.md#beyond-the-thesis has the share measured).
RANDOM_EDGE = 0.12
RANDOM_REFERENCE = 10_000
# Host bytes a triangle takes at the peak of a point (the mesh made, its scene buffer, the
# host builder's arrays and the tree), above the peak measured (docs/thesis.md#beyond-the-thesis):
# a point needing more than the host has free is skipped, not started.
HOST_TRIANGLE_BYTES = 2048


def counts(kind: str, quick: bool) -> tuple[int, ...]:
    """The triangle counts of a kind of mesh, in order."""
    if kind == "icosphere":
        return tuple(20 * 4**k for k in (QUICK_ICOSPHERE_SUBDIVISIONS if quick else ICOSPHERE_SUBDIVISIONS))
    return QUICK_RANDOM_COUNTS if quick else RANDOM_COUNTS


def shadings() -> list[dict]:
    """The shading options of a point: the thesis's (primary rays), then Whitted's."""
    return [{"shading": "thesis"}, {"shading": "whitted", "depth": DEPTH, "shadow_samples": SHADOW_SAMPLES}]


def icosphere(triangles: int):
    """trimesh's icosphere of radius 1 with that many triangles (20 x 4^k), as a raybench Mesh."""
    import trimesh

    from ..meshes import Mesh

    k = round(math.log(triangles / 20, 4))
    if 20 * 4**k != triangles:
        raise ValueError(f"an icosphere has 20 x 4^k triangles, not {triangles:,}")
    m = trimesh.creation.icosphere(subdivisions=k, radius=1.0)
    return Mesh(np.asarray(m.vertices, np.float32), np.asarray(m.faces, np.int32), None)


def random_triangles(n: int, seed: int = 0):
    """n random triangles, seeded: centres uniform in the cube [-1, 1]^3 (the icosphere's box,
    in front of the camera at (0, 0, -2)), each corner its centre plus an offset uniform in a
    cube of side RANDOM_EDGE * sqrt(RANDOM_REFERENCE / n), drawn from
    numpy.random.default_rng([seed, n]): the total area the same at every n. Unshared corners
    (3n vertices), no normals: each triangle flat."""
    from ..meshes import Mesh

    rng = np.random.default_rng([seed, n])
    side = RANDOM_EDGE * math.sqrt(RANDOM_REFERENCE / n)
    centres = rng.uniform(-1.0, 1.0, (n, 1, 3)).astype(np.float32)
    corners = centres + rng.uniform(-side / 2, side / 2, (n, 3, 3)).astype(np.float32)
    faces = np.arange(3 * n, dtype=np.int32).reshape(n, 3)
    return Mesh(corners.reshape(3 * n, 3), faces, None)


def camera():
    from ..camera import Camera

    return Camera(position=EYE, look_at=(0.0, 0.0, 0.0), up=(0.0, 1.0, 0.0), fov_deg=60.0)


@functools.lru_cache(maxsize=1)
def mesh_scene(kind: str, triangles: int, seed: int = 0):
    """The Scene of a point (options "mesh" and "triangles"): the mesh, matte, seen from
    camera(), lit by one light at LIGHT of LIGHT_RADIUS. The last one is kept: a mesh's two
    shadings are measured one after the other."""
    from ..lighting import Light
    from ..scene import Scene
    from ..scene_meshes import SceneMesh

    mesh = icosphere(triangles) if kind == "icosphere" else random_triangles(triangles, seed)
    return Scene([], [], [], camera(), lights=(Light(position=LIGHT, radius=LIGHT_RADIUS),), meshes=[SceneMesh(mesh)])


def too_large(triangles: int) -> str | None:
    """Why a point of that many triangles would not fit on this host, or None where it fits."""
    from ..host import host_available_bytes

    need, free = triangles * HOST_TRIANGLE_BYTES, host_available_bytes()
    if need <= free:
        return None
    return f"needs about {need / 2**30:.1f} GiB on the host, {free / 2**30:.1f} GiB free"


def predicted_ms(pixels: int, triangles: int, measured: list[tuple[int, int, float]]) -> float | None:
    """A frame's time predicted from its series' points measured before, (pixels, triangles,
    median ms) each: linear in pixels; in triangles, the power its last two counts showed
    (from 0, flat, to 1, linear), or linear where only one was measured (the cautious guess)."""
    if not measured:
        return None
    p1, n1, ms1 = measured[-1]
    power = 1.0
    if len(measured) >= 2:
        p0, n0, ms0 = measured[-2]
        if n1 > n0 > 0 and ms0 > 0:
            power = min(max(math.log((ms1 / p1) / (ms0 / p0)) / math.log(n1 / n0), 0.0), 1.0)
    return ms1 * (pixels / p1) * (max(triangles, 1) / max(n1, 1)) ** power
