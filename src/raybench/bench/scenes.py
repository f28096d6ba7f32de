"""The scenes suite: scenes that were not made to flatter a GPU. Haines's Standard
Procedural Databases (raybench.formats.spd), each at size factors 1 to 6, with its own view,
lights and fills, under Whitted shading to SCENES_DEPTH bounces, through the BVH, on every
device asked for, at the thesis's largest size. Spheres and triangles (polygons, patches,
cones cut into triangles: raybench.formats.polygons) are traced in one tree.

Its points are made in suites.py (_scenes), from the sizes here; its section of the report is
report/scenes_section.py. Its verdicts, in the thesis's style: how a frame's cost grows with
the primitive count on each structured scene (the slope of log time against log primitives
over its size factors), and what a GPU buys there beside the secondary suite's random spheres.
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
