"""A scene of both kinds' cpu frames for one version of raybench (its `src/` first on PYTHONPATH,
with a compile cache of its own in RAYBENCH_CACHE_DIR): an icosphere of 4^K * 20 triangles among
random spheres, one tree with typed leaves (kernels/primitives/mixed.py), seen from (0, 0, -3),
1680x1050 on 2 threads, primary rays and Whitted's (N and N / 3 warm frames), each timed by
mesh_frames.timed: the median frame's wall time and hashes of the picture and the hits (the same
in every version).

    RAYBENCH_CACHE_DIR=/tmp/c-a PYTHONPATH=a/src python benchmarks/archive/mixed_frames.py 9 6 8

Run in turn for versions that differ in one thing (the cpu's leaf buffer held in rows or a
primitive's values together: docs/triangles.md, "A triangle's nine values together on the cpu").
"""

import json
import sys

from mesh_frames import timed  # this folder's: the same frames, view and hashes

import raybench
from raybench.bench import meshes
from raybench.mesh_render import mesh_scene

SPHERES = 2000


def scene_of(k: int) -> raybench.Scene:
    """The icosphere of subdivision k and SPHERES random spheres around it, one scene."""
    mesh = mesh_scene(meshes.icosphere(20 * 4**k))
    s = raybench.random_spheres(SPHERES, seed=7, materials=True)
    return mesh.replaced(centers=s.centers, radii=s.radii, colors=s.colors, materials=s.materials)


def main(frames: int, subdivisions: list[int]) -> None:
    out = {}
    for k in subdivisions:
        scene = scene_of(k)
        for shading in ("thesis", "whitted"):
            count = frames if shading == "thesis" else max(1, frames // 3)
            out[f"{20 * 4**k} {shading}"] = timed(scene, count, shading)
    print(json.dumps({"raybench": raybench.__file__, "frames": out}))


if __name__ == "__main__":
    main(int(sys.argv[1]), [int(a) for a in sys.argv[2:]])
