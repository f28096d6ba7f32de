"""--animate: the spheres move every frame (raybench.animate.Orbits, seed 0,
at the request's time), and the tree follows (Renderer.update, or the
window's wgpu pass's: a refit or a build, timed apart from the trace, for the
title).

Used where frames are traced: the worker's thread (cpu, cuda) and the
window's own wgpu pass, each with its own MovingSpheres.
"""

from __future__ import annotations

import time

from ..animate import Orbits


class MovingSpheres:
    """The animation of the requests' scenes, one Orbits a scene."""

    def __init__(self):
        self._orbits: Orbits | None = None
        self._scene = None

    def update(self, traced, request) -> tuple[float | None, str | None]:
        """Move the spheres of `traced` (a Renderer, or anything with its
        update(spheres)) to where request.time puts them, if it has a time:
        (the update's ms, "refit" or "build"); (None, None) if not."""
        if request.time is None:
            return None, None
        if self._scene is not request.scene:
            self._orbits, self._scene = Orbits(request.scene.spheres, 0), request.scene
        spheres = self._orbits.at(request.time)
        start = time.perf_counter()
        kind = traced.update(spheres)
        return (time.perf_counter() - start) * 1e3, kind
