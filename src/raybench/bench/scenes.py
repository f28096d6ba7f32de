"""The scenes suite: scenes that were not made to flatter a GPU. Haines's Standard
Procedural Databases (raybench.formats.spd), each at size factors 1 to 6, with its own view,
lights and fills, under Whitted shading to SCENES_DEPTH bounces, through the BVH, on every
device asked for, at the thesis's largest size. Spheres and triangles (polygons, patches,
cones cut into triangles: raybench.formats.polygons) are traced in one tree.

Its points are made in suites.py (_scenes), from the sizes here; its section of the report is
report/scenes_section.py. Its verdicts, in the thesis's style: how a frame's cost grows with
the primitive count on each structured scene (the slope of log time against log primitives
over its size factors), and what a GPU buys there beside the secondary suite's random spheres.

Molecules too: the shipped example 1tii (raybench.examples: 5,469 atoms without its waters),
spacefill, alone and repeated side by side (formats.assemblies: copies, which the record's
options name with the atom count) to about 10 thousand, 100 thousand, 1 million and 5 million
atoms, with the molecule's own camera and light; its verdict, how a frame grows with the atoms.
"""

from __future__ import annotations

import functools

# Size factors each scene is measured at: 1 to 6 (balls to 597,871 spheres, tetra to 4,096
# triangles, gears to 216 gears); the quick set a few small ones.
SCENES_NAMES = ("balls", "tetra", "mount", "rings", "teapot", "tree", "gears")
SCENES_SIZES = {name: (1, 2, 3, 4, 5, 6) for name in SCENES_NAMES}
QUICK_SCENES_SIZES = {"balls": (1, 2, 3), "tetra": (3,), "gears": (1,)}
SCENES_SIZE = (1680, 1050)
QUICK_SCENES_SIZE = (320, 200)
SCENES_DEPTH = 5
# The molecule, and its copies: 1 (5,469 atoms), 2 (10,938), 18 (98,442), 183 (1,000,827)
# and 914 (4,998,666); the quick set the molecule alone.
MOLECULE = "1tii"
MOLECULE_COPIES = (1, 2, 18, 183, 914)
QUICK_MOLECULE_COPIES = (1,)
MOLECULE_STYLE = "spacefill"


@functools.lru_cache(maxsize=64)
def nff(name: str):
    """The NFF of an option "scene" ("balls 4")."""
    from ..formats import spd

    kind, size = name.split()
    return spd.generate(kind, int(size))


def scene(name: str):
    """The Scene of an option "scene", as the runner traces it."""
    return nff(name).scene()


def primitives(name: str) -> int:
    """Haines's count of the scene's primitives: spheres, polygons, patches and cones."""
    return sum(nff(name).counts().values())


def triangles(name: str) -> int:
    """The triangles raybench traces for the scene's polygons, patches and cones."""
    from ..formats import polygons

    return polygons.count(nff(name))


@functools.lru_cache(maxsize=4)
def molecule_atoms(name: str) -> int:
    """The atoms of one copy of the example molecule `name` as drawn (its waters left out)."""
    return len(_molecule(name, 1))


def molecule_scene(name: str, copies: int):
    """The Scene of `copies` of the example molecule `name` side by side, as the runner traces it."""
    return _molecule(name, copies).scene(MOLECULE_STYLE)


def _molecule(name: str, copies: int):
    from importlib import resources

    from .. import examples
    from ..formats import molecule

    with resources.as_file(examples.path(name)) as path:
        return molecule.read(path, copies=copies)
