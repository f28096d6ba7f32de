"""Example scenes shipped with raybench, loadable by name (`--scene whitted`)
or as files: whitted.json, the classic scene of Whitted's paper made of
spheres only (a huge sphere as the floor, a mirror, a glass ball, an area
light); meshes.json, a scene format version 3 scene of meshes only, each
inline (a floor that mirrors a little, a plastic icosahedron, a glass
tetrahedron, placed by their transforms), traced as triangles; mixed.json,
spheres and meshes in one scene (the same floor and icosahedron, a mirror
ball, a glass ball and a blue one), traced as one tree of both."""

from __future__ import annotations

from importlib import resources

NAMES = ("whitted", "meshes", "mixed")


def path(name: str):
    """The packaged file of the example `name`."""
    return resources.files(__package__).joinpath(f"{name}.json")
