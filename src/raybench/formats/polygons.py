"""NFF's polygons, patches and cones as triangles, and as a Scene's meshes.

NFF has three kinds of primitive besides the sphere: polygons (`p`),
polygon patches (`pp`, a polygon with a normal at each vertex) and cones
or cylinders without caps (`c`). raybench traces spheres and triangles, so:

- a polygon or patch is a fan of triangles (0, i, i + 1) where it is
  convex, and ear-clipped (mapbox_earcut) where it is not, as the SPD's
  gears' toothed faces are; a patch keeps its vertices' normals (smooth
  shading), a polygon is flat;
- a cone is CONE_SEGMENTS quads around its axis, two triangles each, with
  the cone's own normal at every corner, so that its shading is a true
  cone's and only its silhouette is a polygon's (1 - cos(pi / 32), 0.5% of
  the radius, at most), cut into bands along its axis (bands()) so that a
  long cylinder is not slivers as long as itself. A ring of radius 0 (a
  pointed cone's apex) leaves its side's triangles out rather than keep
  triangles of no area.

meshes(nff) gives the Scene's meshes: one SceneMesh for each run of
triangles of one fill, flat or smooth, in the file's order, so that an NFF
written from a Scene (nff.from_scene) reads back to the same triangles in
the same order.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

# Quads around a cone's axis. Haines's programs leave the cone's tessellation
# to the renderer; 32 keeps the silhouette within half a percent of the radius.
CONE_SEGMENTS = 32
# A band's length along the axis, in the cone's larger radius (bands()), and
# the most bands a cone is cut into.
BAND_LENGTH = 2.0
MAX_BANDS = 64


@dataclass(frozen=True)
class Triangles:
    """Triangles as corners (F, 3, 3) and the corners' normals (F, 3, 3),
    float64; fill (F,) int32, the index of each triangle's fill; smooth
    (F,) bool, whether its normals are a surface's (a patch's, a cone's)
    rather than its plane's."""

    corners: np.ndarray
    normals: np.ndarray
    fill: np.ndarray
    smooth: np.ndarray

    def __len__(self) -> int:
        return len(self.corners)

    @classmethod
    def empty(cls) -> Triangles:
        return cls(np.zeros((0, 3, 3)), np.zeros((0, 3, 3)), np.zeros(0, np.int32), np.zeros(0, bool))

    @classmethod
    def joined(cls, parts) -> Triangles:
        parts = [p for p in parts if len(p)]
        if not parts:
            return cls.empty()
        return cls(*(np.concatenate([getattr(p, k) for p in parts]) for k in ("corners", "normals", "fill", "smooth")))


def newell(v: np.ndarray) -> np.ndarray:
    """A polygon's unit normal by Newell's method (the sum of its edges'
    cross terms), right for a concave polygon too; zero for one of no area."""
    nxt = np.roll(v, -1, axis=0)
    n = np.array([np.sum((v[:, 1] - nxt[:, 1]) * (v[:, 2] + nxt[:, 2])),
                  np.sum((v[:, 2] - nxt[:, 2]) * (v[:, 0] + nxt[:, 0])),
                  np.sum((v[:, 0] - nxt[:, 0]) * (v[:, 1] + nxt[:, 1]))])  # fmt: skip
    length = np.linalg.norm(n)
    return n / length if length > 0 else n


def corners_of(v: np.ndarray, normal: np.ndarray) -> np.ndarray:
    """(n - 2, 3) corner indices of a polygon's triangles: a fan (0, i, i + 1)
    where the polygon is convex, as NFF.TXT's polygons are meant to be; where
    it is not (the SPD's gears' toothed faces), mapbox_earcut's ear clipping
    in the plane the normal is most along, each triangle turned the polygon's
    way."""
    n = len(v)
    fan = np.stack([np.zeros(n - 2, np.int64), np.arange(1, n - 1), np.arange(2, n)], axis=1)
    if n == 3:
        return fan
    keep = [a for a in range(3) if a != int(np.argmax(np.abs(normal)))]
    flat = v[:, keep]
    edges = np.roll(flat, -1, axis=0) - flat
    turns = edges[:, 0] * np.roll(edges, -1, axis=0)[:, 1] - edges[:, 1] * np.roll(edges, -1, axis=0)[:, 0]
    if (turns >= 0).all() or (turns <= 0).all():
        return fan
    import mapbox_earcut

    found = mapbox_earcut.triangulate_float64(flat, np.array([n], np.uint32)).reshape(-1, 3).astype(np.int64)
    a, b, c = v[found[:, 0]], v[found[:, 1]], v[found[:, 2]]
    backwards = np.cross(b - a, c - a) @ normal < 0
    found[backwards] = found[backwards][:, ::-1]
    return found


def fans(polygons) -> Triangles:
    """Polygons and patches (nff.Polygon each) as triangles (corners_of); a
    polygon's flat normal is Newell's."""
    corners, normals, fills, smooth = [], [], [], []
    for poly in polygons:
        v = poly.vertices
        if len(v) < 3:
            continue
        face = newell(v)
        which = corners_of(v, face)
        corners.append(v[which])
        if poly.normals is not None:
            normals.append(poly.normals[which])
        else:
            normals.append(np.broadcast_to(face, (len(which), 3, 3)))
        fills.append(np.full(len(which), poly.fill, np.int32))
        smooth.append(np.full(len(which), poly.normals is not None))
    if not corners:
        return Triangles.empty()
    return Triangles(*(np.concatenate(x) for x in (corners, normals, fills, smooth)))


def bands(rows: np.ndarray) -> np.ndarray:
    """How many bands along its axis each cone (K, 8 rows) is cut into: one
    for each BAND_LENGTH of its larger radius along it, so that a long thin
    cylinder is not 2 x CONE_SEGMENTS slivers as long as itself, whose boxes
    (a diagonal cylinder's as large as its own) the tree could not tell apart."""
    rows = np.asarray(rows, np.float64).reshape(-1, 8)
    height = np.linalg.norm(rows[:, 4:7] - rows[:, :3], axis=1)
    widest = np.maximum(np.abs(rows[:, 3]), np.abs(rows[:, 7]))
    with np.errstate(divide="ignore", invalid="ignore"):
        wanted = np.ceil(height / (BAND_LENGTH * widest))
    return np.clip(np.nan_to_num(wanted, nan=1.0, posinf=MAX_BANDS), 1, MAX_BANDS).astype(np.int64)


def cones(rows: np.ndarray, fill: np.ndarray, segments: int = CONE_SEGMENTS) -> Triangles:
    """Cones (K, 8): base x, y, z, radius, apex x, y, z, radius (NFF's `c`;
    a negative radius is read as its size), each bands(rows) bands of
    `segments` quads of two triangles, counter-clockwise seen from outside,
    with the cone's normals; in the cones' order."""
    rows = np.asarray(rows, np.float64).reshape(-1, 8)
    if not len(rows):
        return Triangles.empty()
    fill = np.asarray(fill, np.int32)
    cut = bands(rows)
    parts, owner = [], []
    for m in np.unique(cut).tolist():
        which = np.flatnonzero(cut == m)
        corners, normals, keep = _banded(rows[which], m, segments)
        parts.append((corners[keep], normals[keep]))
        owner.append(np.repeat(which, keep.shape[1])[keep.reshape(-1)] if keep.ndim > 1 else which)
    ids = np.concatenate(owner)
    order = np.argsort(ids, kind="stable")
    corners = np.concatenate([c for c, _ in parts])[order]
    normals = np.concatenate([n for _, n in parts])[order]
    return Triangles(corners, normals, fill[ids[order]], np.ones(len(ids), bool))


def _banded(rows: np.ndarray, m: int, segments: int):
    """Cones cut into m bands: corners and normals (K, T, 3, 3) with T = 2 m
    segments triangles a cone, each band's lower triangles then its upper,
    and keep (K, T): False for those of no area (two corners on a ring of
    radius 0, a pointed cone's tip)."""
    base, base_r = rows[:, :3], np.abs(rows[:, 3])
    apex, apex_r = rows[:, 4:7], np.abs(rows[:, 7])
    axis = apex - base
    height = np.linalg.norm(axis, axis=1)
    # a cone of no height is a flat ring: any axis gives its plane's frame
    a = np.where(height[:, None] > 0, axis / np.where(height > 0, height, 1.0)[:, None], [0.0, 0.0, 1.0])
    # u, v, a right-handed: u is at right angles to a, from the world axis least along it
    least = np.eye(3)[np.argmin(np.abs(a), axis=1)]
    u = np.cross(a, least)
    u /= np.linalg.norm(u, axis=1, keepdims=True)
    v = np.cross(a, u)
    theta = 2.0 * np.pi * np.arange(segments + 1) / segments
    # w (K, S + 1, 3): the outward unit vector at each angle, the last the first again
    w = np.cos(theta)[None, :, None] * u[:, None, :] + np.sin(theta)[None, :, None] * v[:, None, :]
    t = np.arange(m + 1) / m
    centre = base[:, None, :] + t[None, :, None] * axis[:, None, :]  # (K, m + 1, 3)
    radius = base_r[:, None] + t[None, :] * (apex_r - base_r)[:, None]  # (K, m + 1)
    ring = centre[:, :, None, :] + radius[:, :, None, None] * w[:, None, :, :]  # (K, m + 1, S + 1, 3)
    # the side's normal: at right angles to both the ring's tangent and the slant
    # (axis * height + w * (apex_r - base_r)), so w * height + a * (base_r - apex_r)
    n = w * height[:, None, None] + a[:, None, :] * (base_r - apex_r)[:, None, None]
    length = np.linalg.norm(n, axis=2, keepdims=True)
    n = np.divide(n, length, out=np.zeros_like(n), where=length > 0)
    j, k = slice(0, segments), slice(1, segments + 1)
    low, high = ring[:, :-1], ring[:, 1:]  # (K, m, S + 1, 3)
    nn = np.broadcast_to(n[:, None], low.shape)
    lower = np.stack([low[:, :, j], low[:, :, k], high[:, :, k]], axis=3)
    upper = np.stack([low[:, :, j], high[:, :, k], high[:, :, j]], axis=3)
    lower_n = np.stack([nn[:, :, j], nn[:, :, k], nn[:, :, k]], axis=3)
    upper_n = np.stack([nn[:, :, j], nn[:, :, k], nn[:, :, j]], axis=3)
    count = len(rows)
    corners = np.stack([lower, upper], axis=2).reshape(count, -1, 3, 3)  # (K, m, 2, S, 3, 3) flattened
    normals = np.stack([lower_n, upper_n], axis=2).reshape(count, -1, 3, 3)
    keep = np.stack([radius[:, :-1] > 0, radius[:, 1:] > 0], axis=2)  # (K, m, 2)
    keep &= (length[:, 0, 0] > 0)[:, None, None]  # no height and one radius: a circle, no surface
    keep = np.broadcast_to(keep[:, :, :, None], (count, m, 2, segments)).reshape(count, -1)
    return corners, normals, keep


def triangles(nff) -> Triangles:
    """Every triangle of an NFF: its polygons' and patches' fans, then its cones'."""
    return Triangles.joined([fans(nff.polygons), cones(nff.cones, nff.cone_fill)])


def count(nff, segments: int = CONE_SEGMENTS) -> int:
    """len(triangles(nff)), without making them: a polygon of n vertices is n - 2 triangles
    however it is cut, a cone's band 2 segments but where one of its rings has radius 0."""
    fans = sum(max(len(p.vertices) - 2, 0) for p in nff.polygons)
    if not len(nff.cones):
        return fans
    m = bands(nff.cones)
    base, apex = nff.cones[:, 3] != 0, nff.cones[:, 7] != 0
    flat = (np.linalg.norm(nff.cones[:, 4:7] - nff.cones[:, :3], axis=1) == 0) & (
        np.abs(nff.cones[:, 3]) == np.abs(nff.cones[:, 7])
    )
    # every band has both rings of radius > 0 but the first's base and the last's apex
    return fans + int((segments * (2 * m - ~base - ~apex) * ~flat).sum())


def meshes(nff, looks) -> list:
    """The SceneMeshes of an NFF's triangles: one a run of one fill and one
    kind of normals (looks[fill] is its (colour, Material)), each a mesh of
    unshared corners (3 vertices a triangle), smooth ones with their normals."""
    from ..meshes import Mesh
    from ..scene_meshes import SceneMesh

    tri = triangles(nff)
    out = []
    if not len(tri):
        return out
    key = tri.fill.astype(np.int64) * 2 + tri.smooth
    edges = np.flatnonzero(np.diff(key)) + 1
    for a, b in zip(np.concatenate([[0], edges]).tolist(), np.concatenate([edges, [len(key)]]).tolist()):
        n = b - a
        vertices = tri.corners[a:b].reshape(-1, 3).astype(np.float32)
        faces = np.arange(3 * n, dtype=np.int32).reshape(n, 3)
        normals = None
        if tri.smooth[a]:
            normals = tri.normals[a:b].reshape(-1, 3)
            length = np.linalg.norm(normals, axis=1, keepdims=True)
            # a patch's normals made unit (a zero one stays zero: the triangle's surface then takes
            # its plane's); unit ones as they are, so that an exported mesh reads back bit for bit
            off = (np.abs(length - 1.0) > 1e-6) & (length > 0)
            normals = np.where(off, normals / np.where(off, length, 1.0), normals).astype(np.float32)
        colour, material = looks[int(tri.fill[a])]
        out.append(SceneMesh(Mesh(vertices, faces, normals), colour, material))
    return out
