"""A scene's meshes (scene format version 3): each entry of "meshes" read
into a placed mesh with its colour and material, and all of them merged
into one triangle buffer (the triangle primitive's, meshes.mesh_leaves).

An entry names a mesh file (OBJ, PLY, STL, glTF/GLB, read by
meshes.load_mesh), its path relative to the scene file, or holds a small
mesh inline as vertices, faces and optionally per-vertex normals. Its
transform scales, then rotates about x, then y, then z (degrees, right-
handed), then translates: the one order, so that a file says one thing.
The mesh is stored placed (its vertices in the scene's coordinates): what
is traced and what Scene.save writes, inline, with no transform left.

traced(scene) is what a tracer is given: one kind of primitive (the
spheres, the triangles, or both as the mixed kind), its buffer, and what
lighting.Shading.of reads of it (the materials, one per primitive).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from . import lighting
from .camera import MAX_MAGNITUDE
from .errors import RaybenchError, shown
from .fields import no_unknown, numbers
from .layout import MIX_SPHERE, MIX_TRIANGLE, SPHERE_ROWS, TRI_SHADED_ROWS, TRI_SMOOTH_ROWS
from .meshes import MESH_COLOUR, Mesh, Painted, checked_mesh, load_mesh, mesh_leaves

MESH_KEYS = {"file", "vertices", "faces", "normals", "transform", "color", "material"}
TRANSFORM_KEYS = {"translate", "scale", "rotate"}


@dataclass(frozen=True)
class SceneMesh:
    """A mesh placed in a scene: mesh, its vertices in the scene's
    coordinates (meshes.Mesh, float32); colour, every triangle's (R, G, B
    from 0 to 1); material, every triangle's (Whitted shading)."""

    mesh: Mesh
    colour: tuple = MESH_COLOUR
    material: lighting.Material = lighting.MATTE

    def __post_init__(self):
        if not isinstance(self.mesh, Mesh):
            raise RaybenchError(f"meshes: each must hold a raybench.meshes.Mesh, got {type(self.mesh).__name__}")
        object.__setattr__(self, "colour", lighting.check_colour(self.colour, "meshes' color"))
        if not isinstance(self.material, lighting.Material):
            raise RaybenchError(f"meshes' material: must be a raybench.Material, got {type(self.material).__name__}")

    def to_dict(self) -> dict:
        """The entry as a version-3 file holds it, inline (float32 -> float: reloading gives the same bits)."""
        doc = {"vertices": self.mesh.vertices.tolist(), "faces": self.mesh.faces.tolist()}
        if self.mesh.normals is not None:
            doc["normals"] = self.mesh.normals.tolist()
        doc["color"] = list(self.colour)
        if self.material != lighting.MATTE:
            doc["material"] = self.material.to_dict()
        return doc


@dataclass(frozen=True)
class Traced:
    """What one tracer traces: kind, a primitive kind of kernels/primitives'
    KINDS; leaves, its scene buffer (Scene.spheres, or the triangles'), or
    a scene of one mesh's Painted mesh, which backends.tracer takes in its
    place; and what lighting.Shading.of reads: one material per primitive
    (None: all matte), the lights, the ambient light, the background."""

    kind: str
    leaves: np.ndarray | Painted
    materials: tuple | None
    lights: tuple
    ambient: tuple
    background: tuple | None

    def __len__(self) -> int:
        return len(self.leaves) if isinstance(self.leaves, Painted) else self.leaves.shape[1]

    def buffer(self) -> np.ndarray:
        """Its scene buffer, made from a Painted mesh (Painted.leaves) where it holds one."""
        return self.leaves.leaves() if isinstance(self.leaves, Painted) else self.leaves

    @property
    def noun(self) -> str:
        """What a message calls its primitives: spheres, triangles, or
        primitives (spheres and triangles)."""
        return "primitives" if self.kind == "mixed" else f"{self.kind}s"


def merged_materials(meshes) -> tuple | None:
    """The meshes' materials, one a triangle in merged's order; None where all are matte."""
    if any(m.material != lighting.MATTE for m in meshes):
        return tuple(m.material for m in meshes for _ in range(len(m.mesh)))
    return None


def merged(meshes) -> np.ndarray | None:
    """The meshes as one triangle buffer: each mesh's leaves (mesh_leaves,
    in its colour) side by side, with the corners' normals where any mesh
    has them (zeros for one that has none: the triangle's surface then
    takes its plane's normal, as flat shading does). None for no meshes."""
    if not meshes:
        return None
    smooth = any(m.mesh.normals is not None for m in meshes)
    parts = []
    for m in meshes:
        part = mesh_leaves(m.mesh, m.colour)
        if smooth and part.shape[0] < TRI_SMOOTH_ROWS:
            part = np.concatenate([part, np.zeros((TRI_SMOOTH_ROWS - TRI_SHADED_ROWS, part.shape[1]), np.float32)])
        parts.append(part)
    return np.ascontiguousarray(np.concatenate(parts, axis=1))


def mixed_leaves(spheres: np.ndarray, triangles: np.ndarray) -> np.ndarray:
    """The scene's buffer of spheres and triangles together (kernels/
    primitives/mixed.py; layout's MIX_ rows): the spheres' columns, then the
    triangles', each its own kind's rows from row 0 (zeros below a
    sphere's), and the tag in the last row. As tall as the triangles' buffer
    and one more, so a mesh's corners' normals keep their rows."""
    n, f = spheres.shape[1], triangles.shape[1]
    rows = triangles.shape[0]
    out = np.zeros((rows + 1, n + f), np.float32)
    out[:SPHERE_ROWS, :n] = spheres
    out[:rows, n:] = triangles
    out[rows, :n] = MIX_SPHERE
    out[rows, n:] = MIX_TRIANGLE
    return out


def read_meshes(value, base: Path | None) -> list[SceneMesh]:
    """The "meshes" list of a version-3 document; files are relative to base
    (the scene file's folder; None: the current folder)."""
    if not isinstance(value, list):
        raise RaybenchError('meshes: must be a list of {"file"} or {"vertices", "faces"} objects')
    return [read_mesh(entry, f"meshes[{i}]", base) for i, entry in enumerate(value)]


def read_mesh(entry, where: str, base: Path | None) -> SceneMesh:
    if not isinstance(entry, dict):
        raise RaybenchError(f'{where}: must be an object with "file", or "vertices" and "faces"')
    no_unknown(entry, MESH_KEYS, where + ".")
    if "file" in entry:
        inline = sorted({"vertices", "faces", "normals"} & entry.keys())
        if inline:
            raise RaybenchError(f"{where}.{inline[0]}: give a file or vertices and faces, not both")
        mesh = _file(entry["file"], where, base)
    else:
        for key in ("vertices", "faces"):
            if key not in entry:
                raise RaybenchError(f'{where}.{key}: missing (or give "file", a mesh file)')
        mesh = _inline(entry, where)
    mesh = transformed(mesh, read_transform(entry.get("transform", {}), f"{where}.transform"), where)
    colour = lighting.check_colour(entry.get("color", MESH_COLOUR), f"{where}.color")
    material = lighting.MATTE
    if "material" in entry:
        material = lighting.Material.from_dict(entry["material"], f"{where}.material")
    return SceneMesh(mesh, colour, material)


def _file(name, where: str, base: Path | None) -> Mesh:
    if not isinstance(name, str) or not name:
        raise RaybenchError(f"{where}.file: must be a mesh file's path, got {shown(name)}")
    path = Path(name)
    if not path.is_absolute() and base is not None:
        path = base / path
    try:
        return load_mesh(path)
    except RaybenchError as exc:
        raise RaybenchError(f"{where}.file: {exc}") from None


def _rows(value, where: str, kind: str) -> np.ndarray:
    """A list of rows of three numbers (kind "iuf"; "iu": integers) as an
    (n, 3) array, or one line naming what is wrong."""
    what = "whole numbers" if kind == "iu" else "numbers"
    if not isinstance(value, list) or not all(isinstance(row, list) and len(row) == 3 for row in value):
        raise RaybenchError(f"{where}: must be a list of [a, b, c] rows of {what}")
    # NumPy reads true as 1: JSON's booleans are refused before it sees them
    if any(isinstance(v, bool) for row in value for v in row):
        raise RaybenchError(f"{where}: must hold {what}, got a boolean")
    array = np.asarray(value) if value else np.zeros((0, 3), np.int64)
    if array.dtype.kind not in kind:
        raise RaybenchError(f"{where}: must hold {what} (JSON numbers{', no fractions' if kind == 'iu' else ''})")
    return array


def _inline(entry: dict, where: str) -> Mesh:
    vertices = _rows(entry["vertices"], f"{where}.vertices", "iuf").astype(np.float64)
    faces = _rows(entry["faces"], f"{where}.faces", "iu")
    if len(faces) and np.abs(faces).max() >= 2**31:
        raise RaybenchError(f"{where}.faces: a vertex index is at least 2^31")
    normals = None
    if "normals" in entry:
        normals = _rows(entry["normals"], f"{where}.normals", "iuf").astype(np.float64)
        if len(normals) != len(vertices):
            raise RaybenchError(f"{where}.normals: one per vertex: {len(normals)} normals for {len(vertices)} vertices")
    return checked_mesh(where, [(vertices, faces.astype(np.int64), normals)])


@dataclass(frozen=True)
class Transform:
    """Scale (x, y, z factors, each > 0), then rotate about x, y, z in turn
    (degrees), then translate."""

    translate: tuple = (0.0, 0.0, 0.0)
    scale: tuple = (1.0, 1.0, 1.0)
    rotate: tuple = (0.0, 0.0, 0.0)

    def linear(self) -> np.ndarray:
        """The 3x3 matrix of the scale and the rotations, applied to column vectors."""
        matrix = np.diag(np.asarray(self.scale, np.float64))
        for axis, degrees in enumerate(self.rotate):
            c, s = _cos_sin(degrees)
            turn = np.eye(3)
            # the other two axes in cyclic order (y, z about x; z, x about y): right-handed
            i, j = (axis + 1) % 3, (axis + 2) % 3
            turn[i, i], turn[i, j], turn[j, i], turn[j, j] = c, -s, s, c
            matrix = turn @ matrix
        return matrix


def _cos_sin(degrees: float) -> tuple[float, float]:
    """cos and sin of an angle in degrees; exact for quarter turns, so that a
    mesh turned by 90 degrees keeps its vertices' zeros (not 6e-17)."""
    quarters = degrees / 90.0
    if quarters == int(quarters):
        return ((1.0, 0.0), (0.0, 1.0), (-1.0, 0.0), (0.0, -1.0))[int(quarters) % 4]
    return math.cos(math.radians(degrees)), math.sin(math.radians(degrees))


def read_transform(value, where: str) -> Transform:
    if not isinstance(value, dict):
        raise RaybenchError(f"{where}: must be an object with translate, scale, rotate")
    no_unknown(value, TRANSFORM_KEYS, where + ".")
    fields = {}
    if "translate" in value:
        fields["translate"] = tuple(numbers(value["translate"], 3, f"{where}.translate"))
    if "rotate" in value:
        fields["rotate"] = tuple(numbers(value["rotate"], 3, f"{where}.rotate"))
    if "scale" in value:
        scale = value["scale"]
        scale = [numbers(scale, None, f"{where}.scale")] * 3 if not isinstance(scale, list) else scale
        scale = numbers(scale, 3, f"{where}.scale")
        if not all(0 < s <= MAX_MAGNITUDE for s in scale):
            raise RaybenchError(f"{where}.scale: each factor must be > 0 and at most {MAX_MAGNITUDE:g}, got {scale}")
        fields["scale"] = tuple(scale)
    return Transform(**fields)


def transformed(mesh: Mesh, transform: Transform, where: str) -> Mesh:
    """The mesh placed by transform (vertices checked again, in the scene's
    range; normals by the inverse transpose, made unit length again)."""
    if transform == Transform():
        return mesh
    linear = transform.linear()
    vertices = mesh.vertices.astype(np.float64) @ linear.T + np.asarray(transform.translate)
    normals = None
    if mesh.normals is not None:
        normals = mesh.normals.astype(np.float64) @ np.linalg.inv(linear)
    try:
        return checked_mesh(where, [(vertices, mesh.faces.astype(np.int64), normals)])
    except RaybenchError as exc:
        raise RaybenchError(f"{exc} (after its transform)") from None


def traced(scene) -> Traced:
    """The one kind a scene's tracer traces: its spheres where it has no
    meshes (none at all: a scene of no spheres), its triangles where it has
    meshes and no spheres (one mesh: the mesh itself in its colour, Painted,
    of which the cpu makes no scene buffer for primary rays; more: their
    merged buffer), and where it has both the mixed kind (one tree of
    typed leaves, kernels/primitives/mixed.py): the spheres' columns, then
    the triangles' (mixed_leaves), their materials in that order."""
    spheres = scene.spheres
    if not scene.meshes:
        return Traced("sphere", spheres, scene.materials, scene.lights, scene.ambient, scene.background)
    if not spheres.shape[1]:
        one = scene.meshes[0]
        leaves = Painted(one.mesh, one.colour) if len(scene.meshes) == 1 else scene.triangles
        return Traced("triangle", leaves, scene.triangle_materials, scene.lights, scene.ambient, scene.background)
    triangles = scene.triangles
    materials = None
    if scene.materials is not None or scene.triangle_materials is not None:
        ours = scene.materials or (lighting.MATTE,) * spheres.shape[1]
        theirs = scene.triangle_materials or (lighting.MATTE,) * triangles.shape[1]
        materials = tuple(ours) + tuple(theirs)
    return Traced("mixed", mixed_leaves(spheres, triangles), materials, scene.lights, scene.ambient, scene.background)
