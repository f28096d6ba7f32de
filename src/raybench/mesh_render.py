"""A triangle mesh rendered on any device: the mesh's buffer (meshes.mesh_leaves,
the triangle primitive's rows), a camera fitted to its vertices, and for
Whitted shading, as a mesh file brings no lights or materials, one default
light and every triangle matte (DEFAULT_LIGHT_NOTE says so in one line).

MeshScene answers what lighting.Shading.of reads of a Scene (lights,
materials, ambient, background, its length), so Whitted's arrays for a mesh
are made as a sphere scene's are.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .camera import Camera
from .lighting import DEFAULT_AMBIENT, Light, Shading, check_colour, check_shading
from .meshes import MESH_COLOUR, Mesh, mesh_leaves

# What `raybench render` tells a user who asked for Whitted shading of a mesh.
DEFAULT_LIGHT_NOTE = (
    "note: --shading whitted: a mesh file has no lights or materials: it is lit by one white point light "
    "above and behind the camera, every triangle matte (no mirrors or glass, so no bounces)"
)


@dataclass(frozen=True)
class MeshScene:
    """A mesh as a scene: leaves, its triangle buffer (TRI_SHADED_ROWS or
    TRI_SMOOTH_ROWS, F); the camera fitted to it; the lights of Whitted
    shading; materials None (all matte), the default ambient light and the
    thesis's gradient behind it."""

    leaves: np.ndarray
    camera: Camera
    lights: tuple = ()
    materials: None = None
    ambient: tuple = DEFAULT_AMBIENT
    background: None = None

    def __len__(self) -> int:
        """The number of triangles."""
        return self.leaves.shape[1]


def recoloured(scene: MeshScene, colour) -> MeshScene:
    """The scene with every triangle of another colour (checked: three
    numbers from 0 to 1)."""
    from dataclasses import replace

    from .layout import TRI_RED

    leaves = scene.leaves.copy()
    leaves[TRI_RED : TRI_RED + 3] = np.float32(check_colour(colour, "--color")).reshape(3, 1)
    return replace(scene, leaves=leaves)


def mesh_scene(mesh: Mesh, colour=MESH_COLOUR) -> MeshScene:
    """The mesh in one colour, seen by fit_camera's view of its vertices (the
    sphere that bounds them fills the field of view), lit for Whitted
    shading by one white point light above and behind the camera: where
    the camera sees lit faces, whatever the mesh."""
    from .formats import fit_camera

    colour = check_colour(colour, "color")
    vertices = mesh.vertices.astype(np.float64)
    camera = fit_camera(vertices, np.zeros(len(vertices)))
    middle = np.array(camera.look_at)
    reach = float(np.linalg.norm(vertices - middle, axis=1).max()) or 1.0
    eye = np.array(camera.position)
    light = Light(position=tuple((eye + np.array([-reach, 2.0 * reach, -reach])).tolist()))
    return MeshScene(leaves=mesh_leaves(mesh, colour), camera=camera, lights=(light,))


def render_mesh(
    scene: MeshScene,
    width: int = 800,
    height: int = 600,
    device: str = "cpu",
    shading: str = "thesis",
    depth: int | None = None,
    shadow_samples: int | None = None,
    **options,
):
    """One frame of a MeshScene from its camera: a render.Frame. device:
    "cpu", "cuda" or "wgpu" ("auto" picks the cpu); shading, depth and
    shadow_samples as render.render's; options the device's (the cpu's
    threads, tree_width; cuda's block, walk, build, quality, schedule;
    wgpu's adapter, build, walk, schedule; accel: "bvh" or "none" with
    kernel="simple")."""
    from . import backends
    from .backends.limits import check_size
    from .layout import KINDS
    from .render import Frame

    width, height = check_size(width, height)
    whitted = check_shading(shading) == "whitted"
    shaded = Shading.of(scene, depth, shadow_samples) if whitted else None
    tracer = backends.tracer(device, scene.leaves, width, height, shaded, primitive="triangle", **options)
    try:
        image, hits = tracer.trace(scene.camera.basis(width, height))
        counts = tracer.ray_counts
        return Frame(
            image=image.copy(),
            hits=hits.copy(),
            device=tracer.name,
            build_s=tracer.build_s,
            rays=None if counts is None else dict(zip(KINDS, counts.tolist())),
        )
    finally:
        tracer.close()
