"""SPD teapot: Newell's teapot, tessellated, on a checkerboard.

Written from what teapot.c describes (erich666/StandardProceduralDatabases,
CC0): each of the teapot's 32 bicubic Bezier patches (spd_teapot.txt) is
cut into size_factor x size_factor quadrilaterals of equal steps in its two
parameters, each quadrilateral two triangles written as polygon patches
(`pp`), each vertex with the surface's normal there. At the lid's knob and
the bottom's centre a patch's first row is one point (a cusp): a triangle
with two corners there is degenerate and left out, and one with one corner
there gets the normal straight up (lid) or down (bottom) at it, the surface
having none. So 32 * 2 n**2 - 8 n triangles (teapot.c's header: 56, 240, 552
at 1 to 3, 9,120 at 12). Under it a checkerboard of n x n squares, 8 wide,
white squares then grey, both shiny; two lights.
"""

from __future__ import annotations

from importlib import resources

import numpy as np

from .nff import NFF, Polygon, View
from .spd_common import SKY, _fill

# A vertex within this of the z axis, in x and in y, is at a cusp (teapot.c's tolerance).
CUSP = 0.0001
# Cusps above this height are the lid's, below it the bottom's.
CUSP_SPLIT = 1.5
# The checkerboard's half width.
BOARD = 4.0


def _tables(name: str = "spd_teapot.txt") -> dict[str, list[str]]:
    """The teapot's tables, data beside this module: each [section]'s
    numbers as text, comment lines left out."""
    tables: dict[str, list[str]] = {}
    words: list[str] = []
    for line in resources.files(__package__).joinpath(name).read_text(encoding="utf-8").splitlines():
        if line.startswith("["):
            words = tables.setdefault(line.strip("[] "), [])
        elif not line.startswith("#"):
            words += line.split()
    return tables


_TABLES = _tables()
# Each patch's 4 x 4 control points, indices into VERTICES (row r, column c:
# parameters s = r / 3, t = c / 3); the 290 control points, x y z.
PATCHES = np.array(_TABLES["patches"], np.int64).reshape(32, 4, 4)
VERTICES = np.array(_TABLES["vertices"], np.float64).reshape(290, 3)


def _bernstein(u: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The cubic Bernstein polynomials at u (k,) and their derivatives, each (k, 4)."""
    v = 1.0 - u
    basis = np.stack([v**3, 3.0 * u * v * v, 3.0 * u * u * v, u**3], -1)
    slope = np.stack([-3.0 * v * v, 3.0 * v * v - 6.0 * u * v, 6.0 * u * v - 3.0 * u * u, 3.0 * u * u], -1)
    return basis, slope


def surface(size: int) -> tuple[np.ndarray, np.ndarray]:
    """Every patch's points and unit normals on its (n + 1) x (n + 1) grid of
    parameters s, t = i / n, each (32, n + 1, n + 1, 3): the point of s (the
    control rows) and t (the columns), and the normal t-tangent x
    s-tangent, outward; (0, 0, 0) where both tangents' cross is zero (the
    cusps, whose normal the triangles set)."""
    u = np.arange(size + 1) / size
    basis, slope = _bernstein(u)
    control = VERTICES[PATCHES]  # (32, 4, 4, 3)
    points = np.einsum("ir,jc,prcx->pijx", basis, basis, control)
    along_s = np.einsum("ir,jc,prcx->pijx", slope, basis, control)
    along_t = np.einsum("ir,jc,prcx->pijx", basis, slope, control)
    normals = np.cross(along_t, along_s)
    length = np.linalg.norm(normals, axis=-1, keepdims=True)
    normals = np.divide(normals, length, out=np.zeros_like(normals), where=length > 0)
    return points, normals


def tessellate(size: int) -> tuple[np.ndarray, np.ndarray]:
    """The teapot's triangles and their vertices' normals, each (F, 3, 3), in
    teapot.c's order: patch by patch, s step by s step, t step by t step,
    each quadrilateral (s, t), (s, t + 1), (s + 1, t + 1), (s + 1, t) as
    its corners 0, 1, 2 and 2, 3, 0; degenerate triangles at the cusps left
    out and the normal at a cusp set."""
    points, normals = surface(size)
    i, j = np.meshgrid(np.arange(size), np.arange(size), indexing="ij")
    corner_s = np.stack([i, i, i + 1, i + 1], -1)  # (n, n, 4)
    corner_t = np.stack([j, j + 1, j + 1, j], -1)
    which = np.array([[0, 1, 2], [2, 3, 0]])
    s = corner_s[:, :, which]  # (n, n, 2, 3)
    t = corner_t[:, :, which]
    corners = points[:, s, t].reshape(-1, 3, 3)
    norms = normals[:, s, t].reshape(-1, 3, 3)
    on_axis = (np.abs(corners[..., 0]) <= CUSP) & (np.abs(corners[..., 1]) <= CUSP)
    keep = on_axis.sum(axis=1) <= 1
    corners, norms, on_axis = corners[keep], norms[keep].copy(), on_axis[keep]
    up = np.where(corners[..., 2] > CUSP_SPLIT, 1.0, -1.0)
    norms[on_axis] = np.stack([np.zeros_like(up), np.zeros_like(up), up], -1)[on_axis]
    return corners, norms


def checkerboard(size: int) -> tuple[np.ndarray, np.ndarray]:
    """The board's n x n squares (k, 4, 3), counter-clockwise from above,
    as two runs: the white ones (their indices' sum odd), then the grey,
    each in order of x then y step; and whether each is white."""
    steps = [(a, b) for a in range(size) for b in range(size)]
    order = [p for p in steps if sum(p) % 2] + [p for p in steps if not sum(p) % 2]
    k = np.array(order, np.float64).reshape(-1, 2)
    low = BOARD * (2.0 * k / size - 1.0)
    high = BOARD * (2.0 * (k + 1) / size - 1.0)
    x = np.stack([low[:, 0], high[:, 0], high[:, 0], low[:, 0]], -1)
    y = np.stack([low[:, 1], low[:, 1], high[:, 1], high[:, 1]], -1)
    squares = np.stack([x, y, np.zeros_like(x)], -1)
    return squares, np.array([sum(p) % 2 == 1 for p in order], bool)


def teapot(size: int = 6) -> NFF:
    """SPD teapot: the orange, shiny teapot's 32 * 2 size**2 - 8 size
    triangle patches over a size x size checkerboard of shiny white and grey
    squares; two lights. teapot.c's own default size factor is 6; the SPD's
    README tables it at 12 (9,264 primitives)."""
    white = _fill((1.0, 1.0, 1.0), 0.5, 0.5, 30.0, 0.0, 0.0)
    grey = _fill((0.5, 0.5, 0.5), 0.5, 0.5, 30.0, 0.0, 0.0)
    orange = _fill((1.0, 0.5, 0.1), 0.75, 0.25, 37.0, 0.0, 0.0)
    squares, is_white = checkerboard(size)
    polygons = [Polygon(q, None, 0 if w else 1) for q, w in zip(squares, is_white)]
    corners, normals = tessellate(size)
    polygons += [Polygon(c, n, 2) for c, n in zip(corners, normals)]
    view = View((4.86, 7.2, 5.4), (0.0, 0.0, 0.0), (0.0, 0.0, 1.0), 45.0, 1.0, (512, 512))
    lights = [((-3.1, 9.8, 12.1), None), ((11.3, 5.1, 8.8), None)]
    return NFF(view=view, background=SKY, lights=lights, fills=[white, grey, orange], polygons=polygons)
