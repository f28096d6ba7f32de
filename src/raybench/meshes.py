"""Triangle meshes from files: OBJ, PLY, STL and glTF/GLB, read by trimesh
(maintained, pure Python over NumPy, one loader for all four formats and
their variants: ASCII and binary PLY and STL, OBJ's polygons triangulated,
glTF's node transforms), into indexed float32 triangles.

load_mesh(path) gives a Mesh, or raises RaybenchError in one line naming the
file and what is wrong: no such file, a file over MAX_MESH_BYTES, an unknown
format, a file trimesh cannot read, a face index out of range, a non-finite
or too large coordinate, no faces. Degenerate triangles (zero area) load as
they are: the triangle's test never hits them (kernels/primitives/triangle.py).
mesh_leaves(mesh, colour) lays a mesh out as the triangle primitive's scene
buffer (layout's TRI_ rows), every triangle of one colour (default
MESH_COLOUR). A Painted mesh (a mesh and its one colour) is what a tracer
may take in its place: the cpu builds the tree of its primary rays from the
mesh's own arrays and makes no scene buffer (backends/cpu/tracer.py).
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .camera import MAX_MAGNITUDE
from .errors import RaybenchError
from .layout import TRI_A, TRI_B, TRI_C, TRI_NA, TRI_NB, TRI_NC, TRI_RED, TRI_SHADED_ROWS, TRI_SMOOTH_ROWS

# The largest mesh file read, in bytes (1 GiB): a binary PLY of about 40 M
# triangles, an OBJ of about 10 M. trimesh holds a file's text or bytes and
# its float64 arrays at once, several times the file, so a larger file is
# refused before it is read rather than left to run the host out of memory.
MAX_MESH_BYTES = 2**30
# File suffix: trimesh's name for the format.
FORMATS = {".obj": "obj", ".ply": "ply", ".stl": "stl", ".gltf": "gltf", ".glb": "glb"}
# A mesh's colour where none is given: a light grey, which the thesis's
# shading darkens by 1 - cos towards the silhouettes and keeps visible where
# the faces turn away.
MESH_COLOUR = (0.8, 0.8, 0.8)


@dataclass(frozen=True)
class Mesh:
    """Indexed triangles: vertices (V, 3) float32, faces (F, 3) int32 (each a
    row of vertex indices, counter-clockwise seen from the front), and
    normals (V, 3) float32 where the file gives vertex normals, else None."""

    vertices: np.ndarray
    faces: np.ndarray
    normals: np.ndarray | None = None

    def __len__(self) -> int:
        """The number of triangles."""
        return len(self.faces)


def _line(exc: BaseException) -> str:
    """An exception's message on one short line."""
    text = " ".join(str(exc).split()) or type(exc).__name__
    return text if len(text) <= 200 else text[:197] + "..."


def _parts(loaded):
    """(vertices float64, faces int64, normals float64 or None) of each
    triangle mesh in what trimesh loaded: one Trimesh, or a glTF's scene,
    each node's geometry placed by its transform (normals by the inverse
    transpose). Point clouds and paths have no faces and are left out."""
    import trimesh

    if isinstance(loaded, trimesh.Trimesh):
        placed = [(np.eye(4), loaded)]
    elif isinstance(loaded, trimesh.Scene):
        placed = []
        for node in loaded.graph.nodes_geometry:
            transform, name = loaded.graph[node]
            placed.append((np.asarray(transform, np.float64), loaded.geometry[name]))
    else:
        placed = []
    for transform, geometry in placed:
        if not isinstance(geometry, trimesh.Trimesh):
            continue
        vertices = np.asarray(geometry.vertices, np.float64)
        faces = np.asarray(geometry.faces, np.int64).reshape(-1, 3)
        # trimesh computes vertex normals on demand; the file's own are the
        # ones it was given at load, which it keeps in its cache
        cache = getattr(getattr(geometry, "_cache", None), "cache", {})
        normals = np.asarray(cache["vertex_normals"], np.float64) if "vertex_normals" in cache else None
        linear = transform[:3, :3]
        if not np.array_equal(transform, np.eye(4)):
            with np.errstate(invalid="ignore", over="ignore"):  # non-finite vertices: checked_mesh's refusal
                vertices = vertices @ linear.T + transform[:3, 3]
            if normals is not None:
                normals = normals @ np.linalg.inv(linear)
        yield vertices, faces, normals


def load_mesh(path) -> Mesh:
    """The mesh in an OBJ, PLY, STL, glTF or GLB file (by its suffix), as
    indexed float32 triangles; every mesh of a glTF scene, placed, as one."""
    path = Path(path)
    if not path.exists():
        raise RaybenchError(f"{path}: no such file")
    if not path.is_file():
        raise RaybenchError(f"{path}: not a file")
    size = path.stat().st_size
    if size > MAX_MESH_BYTES:
        raise RaybenchError(
            f"{path}: {size:,} bytes, over the {MAX_MESH_BYTES:,}-byte limit for a mesh file (meshes.MAX_MESH_BYTES)"
        )
    kind = FORMATS.get(path.suffix.lower())
    if kind is None:
        raise RaybenchError(
            f"{path}: unknown mesh format {path.suffix or '(no suffix)'!r} (allowed: {', '.join(sorted(FORMATS))})"
        )
    if kind == "gltf":
        # trimesh's glTF reader, given text that is not JSON, goes on to look
        # for a file named model.gltf and reports that missing instead
        try:
            json.loads(path.read_bytes())
        except (ValueError, UnicodeDecodeError) as exc:
            raise RaybenchError(f"{path}: cannot read it as GLTF: not JSON ({_line(exc)})") from None
    import trimesh

    try:
        # process=False: the file's vertices as they are, none merged or dropped
        loaded = trimesh.load(str(path), file_type=kind, process=False)
        parts = list(_parts(loaded))
    except MemoryError:
        raise
    except IndexError as exc:
        # trimesh's OBJ reader indexes its vertices with the faces as it reads
        raise RaybenchError(f"{path}: a face's vertex index is out of range ({_line(exc)})") from None
    except Exception as exc:  # noqa: BLE001 - trimesh's readers raise many kinds for a bad file
        raise RaybenchError(f"{path}: cannot read it as {kind.upper()}: {_line(exc)}") from None
    return checked_mesh(path, parts)


def checked_mesh(path, parts) -> Mesh:
    """One Mesh of the parts ((vertices, faces, normals or None) each), or
    RaybenchError naming the first problem after `path` (a file, or a scene
    file's field: meshes[0])."""
    parts = [p for p in parts if len(p[1])]
    if not parts:
        raise RaybenchError(f"{path}: no faces (a mesh needs at least one triangle)")
    vertices, faces, normals, base = [], [], [], 0
    for v, f, n in parts:
        # trimesh's OBJ reader takes the first vertex line's count of
        # coordinates for them all: "v 0 0" first gives points in a plane
        if np.ndim(v) != 2 or np.shape(v)[1] != 3 or np.ndim(f) != 2 or np.shape(f)[1] != 3:
            raise RaybenchError(
                f"{path}: a vertex needs x, y and z and a face three corners"
                f" (read vertices {np.shape(v)} and faces {np.shape(f)})"
            )
        bad = np.flatnonzero((f < 0).any(axis=1) | (f >= len(v)).any(axis=1))
        if len(bad):
            raise RaybenchError(
                f"{path}: face {base + bad[0]} has vertex index {f[bad[0]].tolist()}, out of range"
                f" (the mesh has {len(v)} vertices)"
            )
        vertices.append(v)
        faces.append(f + base)
        normals.append(n)
        base += len(v)
    vertices = np.concatenate(vertices)
    faces = np.concatenate(faces)
    if not np.isfinite(vertices).all():
        i = int(np.flatnonzero(~np.isfinite(vertices).all(axis=1))[0])
        raise RaybenchError(f"{path}: vertex {i} has a non-finite coordinate {vertices[i].tolist()}")
    if len(vertices) and np.abs(vertices).max() > MAX_MAGNITUDE:
        i = int(np.flatnonzero((np.abs(vertices) > MAX_MAGNITUDE).any(axis=1))[0])
        raise RaybenchError(f"{path}: vertex {i}'s coordinates {vertices[i].tolist()} exceed {MAX_MAGNITUDE:g}")
    if len(faces) >= 2**31 or len(vertices) >= 2**31:
        raise RaybenchError(f"{path}: {len(faces):,} faces and {len(vertices):,} vertices; at most 2^31 - 1 of each")
    smooth = None
    # normals only where every part has them: a mix would shade some smooth, some flat
    if all(n is not None for n in normals):
        smooth = np.concatenate(normals)
        if not np.isfinite(smooth).all():
            i = int(np.flatnonzero(~np.isfinite(smooth).all(axis=1))[0])
            raise RaybenchError(f"{path}: vertex normal {i} is not finite: {smooth[i].tolist()}")
        length = np.linalg.norm(smooth, axis=1, keepdims=True)
        # zero normals stay zero: the triangle's surface falls back to the plane's
        smooth = np.divide(smooth, length, out=np.zeros_like(smooth), where=length > 0).astype(np.float32)
    return Mesh(vertices.astype(np.float32), faces.astype(np.int32), smooth)


def mesh_leaves(mesh: Mesh, colour=MESH_COLOUR) -> np.ndarray:
    """The mesh as the triangle primitive's scene buffer: (TRI_SHADED_ROWS,
    F) float32, layout's TRI_A, TRI_B, TRI_C rows (each face's three
    vertices) and its colour rows (TRI_RED..TRI_BLUE, every face `colour`),
    or (TRI_SMOOTH_ROWS, F) with the corners' normals after them where the
    mesh has vertex normals."""
    n = len(mesh.faces)
    rows = TRI_SHADED_ROWS if mesh.normals is None else TRI_SMOOTH_ROWS
    out = np.empty((rows, n), np.float32)
    # a corner at a time (its x, y, z rows): the three at once made a copy of
    # every face's vertices beside the buffer (docs/triangles.md#memory)
    for corner, (row, normal_row) in enumerate(((TRI_A, TRI_NA), (TRI_B, TRI_NB), (TRI_C, TRI_NC))):
        at = mesh.faces[:, corner]
        out[row : row + 3] = mesh.vertices[at].T
        if mesh.normals is not None:
            out[normal_row : normal_row + 3] = mesh.normals[at].T
    out[TRI_RED : TRI_RED + 3] = np.asarray(colour, np.float32).reshape(3, 1)
    return out


@dataclass(frozen=True)
class Painted:
    """A mesh whose triangles share one colour, which a tracer of triangles takes in place of
    its scene buffer (backends.tracer): each device makes that buffer (leaves()) where it
    reads one, and the cpu's primary rays need none (docs/triangles.md#memory)."""

    mesh: Mesh
    colour: tuple = MESH_COLOUR

    def __len__(self) -> int:
        return len(self.mesh)

    def leaves(self) -> np.ndarray:
        """Its scene buffer: mesh_leaves(mesh, colour)."""
        return mesh_leaves(self.mesh, self.colour)

    def arrays(self) -> tuple[np.ndarray, np.ndarray]:
        """(vertices, faces), float32 and int32, C-contiguous: what the host's builder reads
        through kernels/primitives/triangle_mesh.py."""
        return (
            np.ascontiguousarray(self.mesh.vertices, np.float32),
            np.ascontiguousarray(self.mesh.faces, np.int32),
        )
