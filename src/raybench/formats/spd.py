"""Eric Haines's Standard Procedural Databases (SPD, 1987), generated in Python.

Written from the algorithms that the SPD's C programs and their headers
describe (erich666/StandardProceduralDatabases, CC0), as NumPy arrays a level
at a time rather than the C's recursion; each gives the NFF that program
writes with its default output (OUTPUT_CURVES: spheres, polygons, cones):
the same view, background, lights, fills and primitives, in the same order.

- balls (the sphereflake): a sphere of radius 1/2, and on each sphere nine
  of a third of its radius, size_factor levels deep, over a square floor;
  sum of 9**k for k = 0..size_factor spheres (balls.c's header: 10, 91, 820,
  7381 at 1 to 4) and one polygon.
- tetra: a tetrahedron of tetrahedra, 4**size_factor triangles (tetra.c's
  header: 4, 16, 64 at 1 to 3, 4096 at 6).
- rings: a pyramid of objects of six pentagonal rings of cylinders and
  spheres before a wall; 5 SF (SF + 1) (2 SF + 1) spheres and as many
  cylinders (rings.c's header: 30, 150, 420 at 1 to 3, 4200 at 7) and one
  polygon.
- tree: Aono and Kunii's tree, 2**(size_factor + 1) - 1 cones and as many
  spheres (tree.c's header: 3, 7, 15 at 1 to 3, 4095 at 11) over one field
  polygon.
- gears: size_factor**3 gears, each two faces of 4 * 36 vertices and 144
  side rectangles (gears.c's header: 2, 16, 54, 128 faces and 144, 1152,
  3888, 9216 rectangles at 1 to 4), and one ground polygon.
- mount (spd_mount): a fractal mountain of 2 * 4**size_factor triangles
  (mount.c's header: 8, 32, 128 at 1 to 3, 8192 at 6) and four glass spheres.
- teapot (spd_teapot): Newell's teapot, 32 * 2 n**2 - 8 n triangle patches
  at size factor n (teapot.c's header: 56, 240, 552 at 1 to 3, 9120 at 12),
  on a checkerboard of n**2 squares.

generate(name, size) gives the NFF; SCENES names what there is, with each
one's default size factor (the C's).
"""

from __future__ import annotations

import math

import numpy as np

from ..errors import RaybenchError, shown
from .nff import NFF, Polygon, View
from .spd_common import SKY, _fill, _rotation, phong_power  # noqa: F401 (phong_power: tested as spd's)
from .spd_mount import mount
from .spd_teapot import teapot

# The largest size factor generated: balls at 7 would be 5.4 M spheres,
# tetra at 11 4 M triangles, rings at 60 2.2 M spheres and as many
# cylinders, tree at 20 2 M of each, gears at 20 1.2 M polygons, mount at 10
# 2 M triangles, teapot at 100 639,200 patches; the SPD's own tables stop
# well below.
MAX_SIZE = {"balls": 7, "tetra": 11, "rings": 60, "tree": 20, "gears": 20, "mount": 10, "teapot": 100}


def _flake_directions() -> np.ndarray:
    """The nine unit directions of a sphere's children about +z: three
    directions at right angles to each other, (1, 1, 0), (1, 0, -1) and (0,
    1, -1) over sqrt 2, tipped about (1, -1, 0) by asin(2 / sqrt 6) so that
    their sum points along +z, then turned about z by 0, 120 and 240
    degrees: three trios, each around the parent's upper half."""
    d = 1.0 / math.sqrt(2.0)
    trio = np.array([[d, d, 0.0], [d, 0.0, -d], [0.0, d, -d]])
    tip = _rotation(np.array([1.0, -1.0, 0.0]) / math.sqrt(2.0), math.asin(2.0 / math.sqrt(6.0)))[0]
    trio = trio @ tip.T
    turns = _rotation(np.tile([0.0, 0.0, 1.0], (3, 1)), np.arange(3) * 2.0 * math.pi / 3.0)
    return np.concatenate([trio @ turn.T for turn in turns])


def _onto(directions: np.ndarray) -> np.ndarray:
    """(n, 3, 3) rotations taking +z to each unit direction: none where it is
    (nearly) +z, half a turn about y where it is (nearly) -z, else about
    z x direction by the angle between them; "nearly" within 1e-4 of a
    cosine, as the C tests it, since a child's direction is a unit vector
    only to rounding."""
    n = len(directions)
    dz = directions[:, 2]
    axis = np.stack([-directions[:, 1], directions[:, 0], np.zeros(n)], -1)
    length = np.linalg.norm(axis, axis=1)
    safe = np.where(length > 0, length, 1.0)
    out = _rotation(axis / safe[:, None], np.arccos(np.clip(dz, -1.0, 1.0)))
    out[dz >= 0.9999] = np.eye(3)
    out[dz <= -0.9999] = _rotation(np.array([0.0, 1.0, 0.0]), math.pi)[0]
    return out


def flake(size: int) -> np.ndarray:
    """The sphereflake's spheres, (N, 4) x, y, z, radius, in the order
    balls.c writes them: each sphere, then its nine children's flakes."""
    children = _flake_directions()
    centers = np.zeros((1, 3))
    radii = np.array([0.5])
    directions = np.array([[0.0, 0.0, 1.0]])
    # depth-first position of each sphere: a level's spheres are in their
    # parents' order, each parent's nine together, so a child's place is its
    # parent's, plus one, plus the subtrees of its elder siblings
    place = np.zeros(1, np.int64)
    levels = [(centers, radii, place)]
    for level in range(size):
        subtree = sum(9**k for k in range(size - level))  # the spheres under and including a child
        offsets = np.einsum("nij,kj->nki", _onto(directions), children)  # (n, 9, 3)
        scale = radii * (1.0 + 1.0 / 3.0)
        centers = (centers[:, None, :] + offsets * scale[:, None, None]).reshape(-1, 3)
        radii = np.repeat(radii / 3.0, 9)
        directions = offsets.reshape(-1, 3)
        place = (place[:, None] + 1 + np.arange(9)[None, :] * subtree).reshape(-1)
        levels.append((centers, radii, place))
    total = sum(len(r) for _, r, _ in levels)
    out = np.empty((total, 4))
    for c, r, p in levels:
        out[p, :3] = c
        out[p, 3] = r
    return out


def balls(size: int = 4) -> NFF:
    """SPD balls: the sphereflake on a beige floor, three lights."""
    floor = _fill((1.0, 0.75, 0.33), 0.8, 0.0, 0.0, 0.0, 1.0)
    mirror = _fill((1.0, 0.9, 0.7), 0.5, 0.5, 37.0, 0.0, 1.0)
    view = View((2.1, 1.3, 1.7), (0.0, 0.0, 0.0), (0.0, 0.0, 1.0), 45.0, 0.01, (512, 512))
    lights = [((4.0, 3.0, 2.0), None), ((1.0, -4.0, 4.0), None), ((-3.0, 1.0, 5.0), None)]
    # the floor: a square 24 on a side, half the flake's radius under its centre
    square = np.array([[12.0, 12.0, -0.5], [-12.0, 12.0, -0.5], [-12.0, -12.0, -0.5], [12.0, -12.0, -0.5]])
    spheres = flake(size)
    return NFF(view=view, background=SKY, lights=lights, fills=[floor, mirror], spheres=spheres,
               sphere_fill=np.ones(len(spheres), np.int32), polygons=[Polygon(square, None, 0)])  # fmt: skip


# The four corners of a cube that make a tetrahedron (x * y * z = 1), in the
# order tetra.c visits them (x, then y, then z from -1 to 1).
_CORNERS = np.array([[-1.0, -1.0, 1.0], [-1.0, 1.0, -1.0], [1.0, -1.0, -1.0], [1.0, 1.0, 1.0]])
# Each face's corners, counter-clockwise from outside: face f takes corners
# f, f + 1, f + 2 (mod 4), the first and last swapped on odd faces.
_FACES = ((0, 1, 2), (3, 2, 1), (2, 3, 0), (1, 0, 3))


def tetra(size: int = 6) -> NFF:
    """SPD tetra: a tetrahedron split into four half its size, size - 1
    times, one light; each smallest tetrahedron's four faces are triangles."""
    centers = np.zeros((1, 3))
    half = 1.0
    for _ in range(size - 1):
        half /= 2.0
        centers = (centers[:, None, :] + _CORNERS[None, :, :] * half).reshape(-1, 3)
    fill = _fill((1.0, 0.2, 0.2), 1.0, 0.0, 0.0, 0.0, 0.0)
    polygons = []
    for c in centers:
        corners = c + _CORNERS * half
        polygons += [Polygon(corners[list(face)], None, 0) for face in _FACES]
    view = View((1.022846, -3.177154, -2.174512), (-0.004103, -0.004103, 0.216539), (-0.816497, -0.816497, 0.816497),
                45.0, 1.0, (512, 512))  # fmt: skip
    return NFF(view=view, background=SKY, lights=[((2.0, -18.0, -5.0), None)], fills=[fill], polygons=polygons)


def _dodecahedron_rings(minor: float) -> np.ndarray:
    """The 30 points of rings: the midpoints of a dodecahedron's edges, as
    six pentagons of five, on a sphere of radius 1 / (1 + minor), minor
    being the tubes' radius (rings.c's scale "to fit in a sphere of radius 1"). The first pentagon lies in the xy
    plane from +x; each other is it turned about x by twice the angle whose
    cosine is cos 60 / sin 36 degrees, then about z by an odd number of
    tenths of a turn (1, 3, 5, 7, 9)."""
    scale = 1.0 / (1.0 + minor)
    k = np.arange(5) * 2.0 * math.pi / 5.0
    first = np.stack([scale * np.cos(k), scale * np.sin(k), np.zeros(5)], -1)
    tilt = _rotation(np.array([1.0, 0.0, 0.0]), 2.0 * math.acos(math.cos(math.pi / 3) / math.sin(math.pi / 5)))[0]
    out = [first]
    for p in range(1, 6):
        turn = _rotation(np.array([0.0, 0.0, 1.0]), math.pi * (2.0 * (p - 1) + 1.0) / 5.0)[0]
        out.append(first @ tilt.T @ turn.T)
    return np.concatenate(out)


# rings' tube radius (rings.c: "no derivation given") and ring colours, RGB and complements
RING_RADIUS = 0.07412
RING_COLOURS = ((1.0, 0.0, 0.0), (0.0, 1.0, 0.0), (0.0, 0.0, 1.0), (0.0, 1.0, 1.0), (1.0, 0.0, 1.0), (1.0, 1.0, 0.0))


def rings(size: int = 7) -> NFF:
    """SPD rings: a pyramid of objects, 1, 4, 9, ... size**2 of them a layer
    going away from the eye, each six pentagonal rings (five cylinders and
    five spheres each) of six colours; a white wall behind, three lights.
    5 * size * (size + 1) * (2 size + 1) spheres and as many cylinders."""
    spread = 1.0 / math.sin(math.pi / 8.0)  # a layer's distance from the next: the 45-degree view's
    eye = np.array([-1.0, -spread, 0.5])
    view = View(tuple(eye.tolist()), (-1.0, 1.0 - spread, 0.5), (0.0, 0.0, 1.0), 45.0, 1.0, (512, 512))
    lights = [((3.0, -spread, 3.0), None), ((-4.0, -spread, 1.0), None), ((2.0, -spread, -4.0), None)]
    # the wall just spans the view, 1% to spare, one layer behind the last
    far = spread * (size + 1)
    half = 1.01 * (far - eye[1]) * math.tan(math.pi / 8.0)
    corners = np.array([[1.0, 1.0], [-1.0, 1.0], [-1.0, -1.0], [1.0, -1.0]]) * half
    wall = np.stack([eye[0] + corners[:, 0], np.full(4, far), eye[2] + corners[:, 1]], -1)
    fills = [_fill((1.0, 1.0, 1.0), 1.0, 0.0, 0.0, 0.0, 0.0)]
    fills += [_fill(c, 0.5, 0.2, 37.0, 0.0, 0.0) for c in RING_COLOURS]
    points = _dodecahedron_rings(RING_RADIUS)
    # each of the 30 points starts a cylinder to the point before it on its ring
    previous = np.array([i + 4 if i % 5 == 0 else i - 1 for i in range(30)])
    offsets = [
        (2.0 * x - depth, spread * (depth + 1), 2.0 * z - depth)
        for depth in range(size)
        for z in range(depth + 1)
        for x in range(depth + 1)
    ]
    offsets = np.array(offsets)[:, None, :]
    base = (points[None] + offsets).reshape(-1, 3)
    apex = (points[previous][None] + offsets).reshape(-1, 3)
    n = len(base)
    r = np.full((n, 1), RING_RADIUS)
    which = np.tile(1 + np.arange(30) // 5, len(offsets)).astype(np.int32)
    return NFF(view=view, background=SKY, lights=lights, fills=fills, spheres=np.hstack([base, r]),
               sphere_fill=which, polygons=[Polygon(wall, None, 0)], cones=np.hstack([base, r, apex, r]),
               cone_fill=which)  # fmt: skip


# tree's shape (tree.c's constants): each branch's two children, turned
# from it about x by their branching angles (degrees) and about its axis by
# 90 and 90 + 140 degrees, are shorter by their contractions; radii shrink by
# BRANCH_DIAMETER a generation and along each branch, which is
# BRANCH_WIDTH of its generation's scale wide at its base.
BRANCH_ANGLES = (40.0, 25.0)
BRANCH_TURNS = (90.0, 90.0 + 140.0)
BRANCH_CONTRACTIONS = (0.65, 0.70)
BRANCH_DIAMETER = 0.67
BRANCH_WIDTH = 0.15


def _tree_step(k: int) -> np.ndarray:
    """The 4x4 matrix, for row vectors (p' = p M), from child k's own frame
    to its parent's: turned about x, then about z, then shrunk and moved to
    the parent's tip, z = 1."""
    rx = _rotation(np.array([1.0, 0.0, 0.0]), math.radians(BRANCH_ANGLES[k]))[0]
    rz = _rotation(np.array([0.0, 0.0, 1.0]), math.radians(BRANCH_TURNS[k]))[0]
    out = np.eye(4)
    out[:3, :3] = (rz @ rx).T * BRANCH_CONTRACTIONS[k]
    out[3, 2] = 1.0
    return out


def tree(size: int = 11) -> NFF:
    """SPD tree (Aono and Kunii's method): a trunk, each branch a cone with
    a sphere at its tip and two branches from there, size generations below
    the trunk; on a green field, seven lights. 2**(size + 1) - 1 cones and as
    many spheres."""
    steps = np.stack([_tree_step(0), _tree_step(1)])
    frames = np.eye(4)[None]  # each branch's frame to the world's, row vectors
    scale = 1.0
    place = np.zeros(1, np.int64)  # depth-first position, as tree.c writes them
    parts = []
    for level in range(size + 1):
        base = frames[:, 3, :3]  # (0, 0, 0) in the branch's frame
        apex = frames[:, 2, :3] + frames[:, 3, :3]  # (0, 0, 1)
        r_base = scale * BRANCH_WIDTH
        parts.append((place, base, apex, r_base, r_base * BRANCH_DIAMETER))
        subtree = 2 ** (size - level) - 1  # the branches under and including a child
        frames = np.einsum("kij,njl->nkil", steps, frames).reshape(-1, 4, 4)
        place = (place[:, None] + 1 + np.arange(2)[None, :] * subtree).reshape(-1)
        scale *= BRANCH_DIAMETER
    total = 2 ** (size + 1) - 1
    cones, spheres = np.empty((total, 8)), np.empty((total, 4))
    for where, base, apex, r0, r1 in parts:
        cones[where, :3], cones[where, 3], cones[where, 4:7], cones[where, 7] = base, r0, apex, r1
        spheres[where, :3], spheres[where, 3] = apex, r1
    field = np.array([[50.0, 50.0, 0.0], [-50.0, 50.0, 0.0], [-50.0, -50.0, 0.0], [50.0, -50.0, 0.0]])
    fills = [_fill((0.2, 0.7, 0.2), 1.0, 0.0, 0.0, 0.0, 0.0), _fill((0.55, 0.4, 0.2), 1.0, 0.0, 0.0, 0.0, 0.0)]
    lights = [(p, None) for p in ((-5.0, 5.0, 50.0), (30.0, -30.0, 30.0), (-40.0, -30.0, 20.0), (10.0, 30.0, 40.0),
                                  (-30.0, 40.0, 10.0), (50.0, 25.0, 20.0), (-10.0, -60.0, 30.0))]  # fmt: skip
    view = View((4.5, 0.4, 2.0), (0.0, 0.0, 1.5), (0.0, 0.0, 1.0), 45.0, 1.0, (512, 512))
    which = np.ones(total, np.int32)
    return NFF(view=view, background=SKY, lights=lights, fills=fills, spheres=spheres, sphere_fill=which,
               polygons=[Polygon(field, None, 0)], cones=cones, cone_fill=which)  # fmt: skip


# gears' shape (gears.c's constants): teeth a gear (a multiple of 4); the
# teeth's tips a little inside the gear's radius, so that meshing gears
# never share a surface; the teeth's roots; the thickness to the width.
TEETH = 36
OUTER_EDGE = 0.995
INNER_EDGE = 0.9
DEPTH_RATIO = 0.1


def _gear_face(centre, turn: float, outer: float, inner: float, z: float, sense: float) -> np.ndarray:
    """A gear face's 4 TEETH points: each tooth's two tip corners (at
    -0.19 and +0.19 of a tooth's angle, radius `outer`) and two root
    corners (+0.3, +0.7, radius `inner`), the teeth going round by `sense`
    (+1 anticlockwise for the top face, -1 for the bottom) from `turn`."""
    tooth = sense * 2.0 * math.pi / TEETH
    start = turn + sense * 2.0 * math.pi * np.arange(TEETH) / TEETH
    angles = (start[:, None] + tooth * np.array([-0.19, 0.19, 0.3, 0.7])[None, :]).reshape(-1)
    radii = np.tile([outer, outer, inner, inner], TEETH)
    return np.stack([centre[0] + radii * np.cos(angles), centre[1] + radii * np.sin(angles),
                     np.full(len(angles), centre[2] + z)], -1)  # fmt: skip


def gears(size: int = 4) -> NFF:
    """SPD gears: size**3 gears in a cube, meshing, each a top and a bottom
    face of 144 vertices (concave) and 144 rectangles round its side; every
    fifth gear glass; on a reflective ground square, five lights."""
    fills = [_fill((1.0, 0.85, 0.7), 0.3, 0.6, 37.0, 0.0, 0.0)]
    ground = np.array([[2.0, 2.0, 0.0], [-2.0, 2.0, 0.0], [-2.0, -2.0, 0.0], [2.0, -2.0, 0.0]])
    polygons = [Polygon(ground, None, 0)]
    edge = 1.0 - INNER_EDGE
    radius = 1.0 / (size - (size - 1) * edge / 2.0)
    first = -1.0 + radius
    step = radius * (2.0 - edge)
    thickness = min(DEPTH_RATIO, 1.0 / (2.0 * size))
    for iz in range(size):
        for iy in range(size):
            for ix in range(size):
                centre = (first + ix * step, first + iy * step, 1.0 - iz / size)
                # a colour from the gear's place, brightest channel 1
                rgb = [0.01 + (k * f) % 1.0 for k, f in ((ix * 3 + iy * 2 + iz + 1, 5 / 7),
                       (iy * 3 + iz * 2 + ix + 1, 3 / 7), (iz * 3 + ix * 2 + iy + 1, 2 / 7))]  # fmt: skip
                rgb = tuple(c / max(rgb) for c in rgb)
                glass = (ix * 4 + iy * 2 + iz) % 5 == 0
                fills.append(_fill(rgb, 0.2, 0.0, 0.0, 0.8, 1.1) if glass else _fill(rgb, 1.0, 0.0, 0.0, 0.0, 0.0))
                fill = len(fills) - 1
                turn = math.pi * ((ix + iy + iz) % 2) / TEETH  # neighbours' teeth between each other's
                outer, inner = OUTER_EDGE * radius, (1.0 - edge) * radius
                top = _gear_face(centre, turn, outer, inner, 0.0, 1.0)
                polygons.append(Polygon(top, None, fill))
                below = top - [0.0, 0.0, thickness]
                after = np.roll(np.arange(len(top)), -1)
                sides = np.stack([top, below, below[after], top[after]], axis=1)
                polygons += [Polygon(side, None, fill) for side in sides]
                polygons.append(Polygon(_gear_face(centre, turn, outer, inner, -thickness, -1.0), None, fill))
    lights = [(p, None) for p in ((2.0, 4.0, 4.0), (-2.0, 4.0, 3.0), (2.0, -2.5, 2.5), (-1.0, -4.0, 2.0),
                                  (-1.111, -2.121, 2.626))]  # fmt: skip
    view = View((-1.1, -2.1, 2.6), (0.0, 0.0, 0.0), (0.0, 0.0, 1.0), 45.0, 1.0, (512, 512))
    return NFF(view=view, background=SKY, lights=lights, fills=fills, polygons=polygons)


# name: (generator, default size factor, the C's)
SCENES = {"balls": (balls, 4), "tetra": (tetra, 6), "rings": (rings, 7), "tree": (tree, 11), "gears": (gears, 4),
          "mount": (mount, 6), "teapot": (teapot, 6)}  # fmt: skip


def generate(name: str, size: int | None = None) -> NFF:
    """The SPD scene `name` at size factor `size` (its default where None)."""
    if name not in SCENES:
        raise RaybenchError(f"SPD scene: one of {', '.join(SCENES)}, got {shown(name)}")
    make, default = SCENES[name]
    size = default if size is None else size
    if isinstance(size, bool) or not isinstance(size, int) or not 1 <= size <= MAX_SIZE[name]:
        raise RaybenchError(f"--size: {name}'s size factor is a whole number from 1 to {MAX_SIZE[name]}, "
                            f"got {shown(size)}")  # fmt: skip
    return make(size)
