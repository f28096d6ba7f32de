"""The scenes suite: scenes that were not made to flatter a GPU. Haines's Standard
Procedural Databases (raybench.formats.spd) at each size factor where a frame fits a point's
time, each with its own view, lights and fills, under Whitted shading to SCENES_DEPTH bounces,
through the BVH, on every device asked for, at the thesis's largest size.

raybench renders spheres only until triangles reach its renderers: balls' floor, rings' and
tree's floors and cylinders are read and not drawn, and each point says so in its options
("unrendered"); tetra and gears are polygons only, so they have no point yet, and the report
names them (POLYGONS_ONLY) rather than leaving them out unsaid. Molecules join once one ships
in the package (benchmarks/peers.py times them against PyMOL from PyMOL's own files).

Its points are made in suites.py (_scenes), from the sizes here; its section of the report is
report/scenes_section.py. Its verdict, in the thesis's style: how a frame's cost grows with the primitive count on a
structured scene (the slope of log time against log spheres over balls' size factors), and
what a GPU buys there beside the secondary suite's random spheres.
"""

from __future__ import annotations

import functools

# Size factors a scene is measured at: balls to 597,871 spheres; rings and tree at their
# largest and their default (their sphere counts stay small).
SCENES_SIZES = {"balls": (1, 2, 3, 4, 5, 6), "rings": (4, 7), "tree": (7, 11)}
QUICK_SCENES_SIZES = {"balls": (1, 2, 3)}
SCENES_SIZE = (1680, 1050)
QUICK_SCENES_SIZE = (320, 200)
SCENES_DEPTH = 5
POLYGONS_ONLY = ("tetra", "gears")


@functools.lru_cache(maxsize=16)
def nff(name: str):
    """The NFF of an option "scene" ("balls 4")."""
    from ..formats import spd

    kind, size = name.split()
    return spd.generate(kind, int(size))


def scene(name: str):
    """The Scene of an option "scene", as the runner traces it."""
    return nff(name).scene()


def unrendered(name: str) -> str:
    """What the scene holds that raybench reads and does not render yet ("" where nothing)."""
    from ..formats.nff import counted

    counts = nff(name).counts()
    return " and ".join(counted(counts[k], k) for k in ("polygons", "patches", "cones") if counts[k])
