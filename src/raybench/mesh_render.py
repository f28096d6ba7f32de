"""A mesh file as a scene: `raybench render --scene model.ply` and
`raybench view --scene model.obj`. A mesh file brings no camera, lights or
materials, so mesh_scene gives it a camera fitted to its vertices and, for
Whitted shading, one default light, every triangle matte
(DEFAULT_LIGHT_NOTE says so in one line). The Scene it makes is traced as
any other, through render.Renderer.
"""

from __future__ import annotations

import numpy as np

from .lighting import Light, check_colour
from .meshes import MESH_COLOUR, Mesh
from .scene import Scene
from .scene_meshes import SceneMesh

# What `raybench render` tells a user who asked for Whitted shading of a mesh.
DEFAULT_LIGHT_NOTE = (
    "note: --shading whitted: a mesh file has no lights or materials: it is lit by one white point light "
    "above and behind the camera, every triangle matte (no mirrors or glass, so no bounces)"
)


def mesh_scene(mesh: Mesh, colour=MESH_COLOUR) -> Scene:
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
    return Scene([], [], [], camera, lights=(light,), meshes=[SceneMesh(mesh, colour)])


def recoloured(scene: Scene, colour) -> Scene:
    """The scene with every mesh in another colour (checked: three numbers
    from 0 to 1)."""
    from dataclasses import replace

    colour = check_colour(colour, "--color")
    return scene.replaced(meshes=[replace(mesh, colour=colour) for mesh in scene.meshes])


def render_mesh(scene: Scene, width: int = 800, height: int = 600, device: str = "cpu", **arguments):
    """render.render of a mesh scene from its camera, device cpu unless
    given: kept for the callers of the first mesh API (render() takes a mesh
    scene itself, as every scene)."""
    from .render import render

    return render(scene, None, width, height, device, **arguments)
