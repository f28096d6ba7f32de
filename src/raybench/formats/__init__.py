"""Scene sources beside the JSON scene file (docs/design: "Scene sources
beside the scene"): each turns a file or a generator into the same Scene of
spheres, materials and lights.

- nff: Eric Haines's Neutral File Format, read and written;
- spd: the Standard Procedural Databases' generators, written from their
  algorithms, giving NFF;
- molecule: PDB and mmCIF files through gemmi, one sphere per atom;
- mesh: OBJ, PLY, STL and glTF triangle meshes (raybench.meshes), a Scene
  of meshes by mesh_render.mesh_scene.

kind(path) names the reader a file's suffix picks; fit_camera frames
spheres where a file gives no view.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from ..meshes import FORMATS

# suffix: the reader's module (imported on use: gemmi only for molecules)
NFF_SUFFIXES = (".nff",)
MOLECULE_SUFFIXES = (".pdb", ".ent", ".cif", ".mmcif")


def kind(path) -> str | None:
    """'nff', 'molecule', 'mesh' (meshes.FORMATS: a triangle mesh) or None
    (a JSON scene file) by the path's suffix, a compressed molecule's
    (.pdb.gz, .cif.gz) included."""
    name = Path(path).name.lower()
    if name.endswith(".gz"):
        name = name[:-3]
    suffix = Path(name).suffix
    if suffix in NFF_SUFFIXES:
        return "nff"
    if suffix in MOLECULE_SUFFIXES:
        return "molecule"
    if suffix in FORMATS:
        return "mesh"
    return None


# A fitted view: raybench's default field of view, and the room left
# around the scene's bounding sphere, as a share of its radius.
FIT_FOV_DEG = 60.0
FIT_MARGIN = 1.1


def fit_camera(centers, radii, fov_deg: float = FIT_FOV_DEG):
    """A Camera that sees every sphere (centers (n, 3), radii (n,), n >= 1):
    it looks along +z, raybench's default direction, at the centre of the
    spheres' box, from where the sphere bounding them all fills the
    vertical field of view with FIT_MARGIN to spare."""
    from ..camera import Camera

    centers = np.asarray(centers, np.float64)
    radii = np.asarray(radii, np.float64)
    low = (centers - radii[:, None]).min(axis=0)
    high = (centers + radii[:, None]).max(axis=0)
    middle = (low + high) / 2
    reach = float((np.linalg.norm(centers - middle, axis=1) + radii).max())
    distance = FIT_MARGIN * reach / math.sin(math.radians(fov_deg) / 2)
    position = middle - np.array([0.0, 0.0, distance])
    return Camera(position=tuple(position.tolist()), look_at=tuple(middle.tolist()), fov_deg=fov_deg)
