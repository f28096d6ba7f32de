"""Example scenes shipped with raybench, loadable by name (`--scene whitted`)
or as files: whitted.json, the classic scene of Whitted's paper made of
spheres only (a huge sphere as the floor, a mirror, a glass ball, an area
light); meshes.json, a scene format version 3 scene of meshes only, each
inline (a floor that mirrors a little, a plastic icosahedron, a glass
tetrahedron, placed by their transforms), traced as triangles; mixed.json,
spheres and meshes in one scene (the same floor and icosahedron, a mirror
ball, a glass ball and a blue one), traced as one tree of both; 1tii.pdb.gz,
a molecule: the Protein Data Bank's entry 1TII (E. coli heat-labile
enterotoxin type IIB, van den Akker and Hol, 1996; 5,684 atoms, 5,469 without
its waters), the file as PyMOL's demo data ships it (pymol-data's
data/demo/1tii.pdb), gzipped. The PDB's entries are in the public domain
(CC0, wwPDB's usage policy), so it ships with raybench, and tests and the
scenes suite need no PyMOL for it."""

from __future__ import annotations

from importlib import resources

# name: its file in this package
FILES = {"whitted": "whitted.json", "meshes": "meshes.json", "mixed": "mixed.json", "1tii": "1tii.pdb.gz"}
NAMES = tuple(FILES)


def path(name: str):
    """The packaged file of the example `name` (a Traversable: a path where raybench is
    installed as files, as pip installs it)."""
    return resources.files(__package__).joinpath(FILES[name])
