"""SPD mount: Haines's fractal mountain and its pyramid of crystal spheres.

Written from the algorithm mount.c describes (erich666/StandardProceduralDatabases,
CC0): Carpenter's midpoint subdivision of a square, 2 wide, from -1 to 1 in
x and y, flat at z = 0 at its corners. Each square's four edge midpoints and
its centre rise by a Gaussian deviate times a height that halves with the
square (times the roughness of fractal dimension 2.2; the centre's times
sqrt 2), until the squares are 2 / 2**size_factor wide; each is then two
triangles, 2 * 4**size_factor in all (mount.c's header: 8, 32, 128 at 1 to 3,
8192 at 6). In front of it, on the mountain's upper left, four touching
glass spheres in a tetrahedron. One light.

The deviates are what makes this mountain the SPD's own, so they are Haines's
exactly: each point's deviate is lib_gauss_rand (Numerical Recipes' GASDEV
polar method over a linear congruential generator) seeded by mount.c's
"old, faulty" hash of the point's grid coordinates and the size factor,
which the SPD keeps for its comparison tests (it repeats within the
mountain: the hash has 16 bits). Since a point's seed depends only on where it
is, the whole grid is computed a level at a time rather than by the C's
recursion, and the triangles written in the recursion's order.
"""

from __future__ import annotations

import functools
import math

import numpy as np

from .nff import NFF, Polygon, View
from .spd_common import SKY, _fill, _rotation

# mount.c's constants: the fractal dimension (between 2 and 3: the higher,
# the rougher), and the number added to every seed ("change MOUNTAIN_NO to
# get a different mountain").
FRACTAL_DIMENSION = 2.2
MOUNTAIN_NO = 21
# lib_gauss_rand's linear congruential generator: x' = (IC + x IA) mod M.
GAUSS_M, GAUSS_A, GAUSS_C = 134456, 8121, 28411
# The crystal spheres' pyramid: the centre of its four spheres, their radius.
CRYSTAL_CENTRE = (-0.8, 0.8, 1.0)
CRYSTAL_RADIUS = 0.17


def gauss_rand(seed: int) -> float:
    """Haines's lib_gauss_rand(seed): the polar (Box-Muller) method's first
    deviate of a pair of uniform deviates in (-1, 1) from two steps of the
    generator, stepping on until the pair falls inside the unit circle.
    Written with the C's operations in the C's order, (x * 2.0) / M - 1.0
    and math's log and sqrt (the C library's), so that every bit agrees."""
    ix2 = seed
    while True:
        ix1 = (GAUSS_C + ix2 * GAUSS_A) % GAUSS_M
        ix2 = (GAUSS_C + ix1 * GAUSS_A) % GAUSS_M
        v1 = ix1 * 2.0 / GAUSS_M - 1.0
        v2 = ix2 * 2.0 / GAUSS_M - 1.0
        r = v1 * v1 + v2 * v2
        if r < 1.0:
            return v1 * math.sqrt(-2.0 * math.log(r) / r)


@functools.cache
def _gauss_table() -> np.ndarray:
    """gauss_rand of every seed the mountain can ask for: MOUNTAIN_NO plus a
    16-bit hash (the hash's & 0xffff), 65,536 of them, each computed once."""
    return np.array([gauss_rand(MOUNTAIN_NO + h) for h in range(0x10000)])


def grid_hash(a: np.ndarray, b: np.ndarray, size: int) -> np.ndarray:
    """mount.c's old hash of grid point (a, b) at size factor size:
    (a << (23 - size)) + (b << (15 - size)) + (a << (7 - size)), its low 16
    bits. Past size 7 the last shift is negative (and past 15 the second),
    which C leaves undefined; the term is taken as 0, as the C compiled by
    gcc on x86-64 gives it (its shift counts wrap to 64 + the count, at
    least 16, and the 16 bits kept are zero: checked against that program's
    output at sizes 8 and 9)."""
    a = np.asarray(a, np.int64)
    b = np.asarray(b, np.int64)
    total = np.zeros(np.broadcast(a, b).shape, np.int64)
    for value, shift in ((a, 23 - size), (b, 15 - size), (a, 7 - size)):
        if shift >= 0:
            total += value << shift
    return total & 0xFFFF


def roughness() -> float:
    """How much a midpoint may rise for each unit of the square's half
    width: sqrt(ratio**2 - 1), ratio being 2 / 2**(1 / (D - 1)) for fractal
    dimension D (Carpenter's scaling)."""
    ratio = 2.0 / math.exp(math.log(2.0) / (FRACTAL_DIMENSION - 1.0))
    return math.sqrt(ratio * ratio - 1.0)


def heights(size: int) -> np.ndarray:
    """The mountain's heights z[x, y] at the (n + 1)**2 grid points, n =
    2**size: each level's squares (width w, lower left corner (x, y)) set
    their edge midpoints and centre from their corners. A midpoint shared by
    two squares gets the same value from both (the same two corners summed,
    the same seed), so writing it twice is harmless."""
    n = 2**size
    table = _gauss_table()
    rough = roughness()
    z = np.zeros((n + 1, n + 1))
    width = n
    while width > 1:
        half = width // 2
        rise = half * 2.0 / n * rough  # the half side's length times the roughness, in the C's order
        x, y = np.meshgrid(np.arange(0, n, width), np.arange(0, n, width), indexing="ij")
        ll, lr, ur, ul = z[x, y], z[x + width, y], z[x + width, y + width], z[x, y + width]

        def deviate(a, b):
            return table[grid_hash(a, b, size)]

        z[x + half, y] = (ll + lr) / 2.0 + rise * deviate(x + half, y)
        z[x + width, y + half] = (lr + ur) / 2.0 + rise * deviate(x + width, y + half)
        z[x + half, y + width] = (ur + ul) / 2.0 + rise * deviate(x + half, y + width)
        z[x, y + half] = (ul + ll) / 2.0 + rise * deviate(x, y + half)
        # the centre is a diagonal's half width, sqrt 2 times an edge's, from the corners
        z[x + half, y + half] = (ll + lr + ur + ul) / 4.0 + 1.4142136 * rise * deviate(x + half, y + half)
        width = half
    return z


def square_order(size: int) -> np.ndarray:
    """The unit squares' lower left corners (n * n, 2), in the order the
    C's recursion reaches them: each square's quarters lower left, lower
    right, upper right, upper left, the first level's quarters outermost."""
    n = 2**size
    x, y = np.meshgrid(np.arange(n), np.arange(n), indexing="ij")
    x, y = x.reshape(-1), y.reshape(-1)
    key = np.zeros(n * n, np.int64)
    for bit in range(size - 1, -1, -1):
        qx, qy = (x >> bit) & 1, (y >> bit) & 1
        key = key * 4 + np.where(qy == 0, qx, 3 - qx)  # (0, 0) 0, (1, 0) 1, (1, 1) 2, (0, 1) 3
    order = np.argsort(key, kind="stable")
    return np.stack([x[order], y[order]], -1)


def mountain(size: int) -> np.ndarray:
    """The mountain's triangles (2 * 4**size, 3, 3), as mount.c writes
    them: each unit square in square_order's order, split along its diagonal
    from lower left to upper right into (ll, lr, ur) and (ur, ul, ll),
    counter-clockwise from above."""
    n = 2**size
    z = heights(size)
    corners = square_order(size)
    x, y = corners[:, 0], corners[:, 1]
    # x = -1 + x * 2 / n, in the C's order of operations
    left, right = -1.0 + x * 2.0 / n, -1.0 + (x + 1) * 2.0 / n
    low, high = -1.0 + y * 2.0 / n, -1.0 + (y + 1) * 2.0 / n
    ll = np.stack([left, low, z[x, y]], -1)
    lr = np.stack([right, low, z[x + 1, y]], -1)
    ur = np.stack([right, high, z[x + 1, y + 1]], -1)
    ul = np.stack([left, high, z[x, y + 1]], -1)
    return np.stack([np.stack([ll, lr, ur], 1), np.stack([ur, ul, ll], 1)], 1).reshape(-1, 3, 3)


def crystal_spheres(centre=CRYSTAL_CENTRE, radius: float = CRYSTAL_RADIUS) -> np.ndarray:
    """The pyramid of four touching spheres (4, 4) about centre: one
    radius sqrt(3 / 2) straight above it (a regular tetrahedron of edge 2
    radius has its corners that far from its centre), then the three
    others, that point turned about (1, 1, 0) by the tetrahedron's central
    angle acos(-1/3) and then about z by 0, 120 and 240 degrees."""
    centre = np.asarray(centre, np.float64)
    top = np.array([0.0, 0.0, radius * math.sqrt(1.5)])
    tilt = _rotation(np.array([1.0, 1.0, 0.0]) / math.sqrt(2.0), math.acos(-1.0 / 3.0))[0]
    turns = _rotation(np.tile([0.0, 0.0, 1.0], (3, 1)), np.arange(3) * 2.0 * math.pi / 3.0)
    offsets = np.concatenate([top[None], turns @ (tilt @ top)])
    return np.hstack([centre + offsets, np.full((4, 1), radius)])


def mount(size: int = 6) -> NFF:
    """SPD mount: the fractal mountain, grey and matte, 2 * 4**size
    triangles, and the four glass spheres before it; one light, far off to
    the upper left of the view."""
    glass = _fill((1.0, 1.0, 1.0), 0.1, 0.1, 6.7, 0.9, 1.5)
    rock = _fill((0.5, 0.45, 0.35), 1.0, 0.0, 0.0, 0.0, 0.0)
    view = View((-1.6, 1.6, 1.7), (0.0, 0.0, 0.0), (0.0, 0.0, 1.0), 45.0, 0.01, (512, 512))
    spheres = crystal_spheres()
    polygons = [Polygon(t, None, 1) for t in mountain(size)]
    return NFF(view=view, background=SKY, lights=[((-100.0, -100.0, 100.0), None)], fills=[glass, rock],
               spheres=spheres, sphere_fill=np.zeros(len(spheres), np.int32), polygons=polygons)  # fmt: skip
