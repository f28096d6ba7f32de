"""The SPD's scenes' cpu frames for one version of raybench (its `src/` first on PYTHONPATH, with
a compile cache of its own in RAYBENCH_CACHE_DIR): each scene of bench.scenes by name (`balls 3`:
a sphereflake on a floor of two triangles, `rings 3`, `tree 6`: spheres among meshes' triangles),
from its own camera, 1680x1050 on 2 threads, timed by mesh_frames.timed: the median frame's wall
time and hashes of the picture and the hits (the same in every version).

    RAYBENCH_CACHE_DIR=/tmp/c-a PYTHONPATH=a/src python benchmarks/archive/spd_frames.py 9 thesis \\
        "balls 3" "rings 3" "tree 6"

Run in turn for the versions compared (a scene of both kinds in the cpu's packets:
docs/notes/mixed-scenes.md, "The cpu's packets: each kind's own test").
"""

import json
import sys

from mesh_frames import timed  # this folder's: the same frames and hashes

import raybench
from raybench.bench import scenes


def main(frames: int, shading: str, names: list[str]) -> None:
    out = {}
    for name in names:
        scene = scenes.scene(name)
        out[name] = timed(scene, frames, shading, scene.camera)
    print(json.dumps({"raybench": raybench.__file__, "frames": out}))


if __name__ == "__main__":
    main(int(sys.argv[1]), sys.argv[2], sys.argv[3:] or ["balls 3", "rings 3", "tree 6"])
