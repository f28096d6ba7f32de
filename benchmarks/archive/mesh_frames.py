"""A mesh's cpu frames for one version of raybench (its `src/` first on PYTHONPATH, with a compile
cache of its own in RAYBENCH_CACHE_DIR): the meshes suite's icosphere at each subdivision, seen from
(0, 0, -3) (the view of `peers.py embreex`), 1680x1050 on 2 threads, primary rays, the median of N
warm frames of wall time, and hashes of the picture and the hits (the same in every version).

    RAYBENCH_CACHE_DIR=/tmp/c-16x8 PYTHONPATH=v16x8/src python benchmarks/archive/mesh_frames.py 21 6 7 8
    ... mesh_frames.py 9 8 --shuffled    (the faces in a random order)
    ... mesh_frames.py 3 8 --whitted     (Whitted's shading)

Run in turn for versions that differ in one thing (the packets' shape: a copy of the source with
PACKET_SHAPE in kernels/primitives/triangle.py changed). The figures: docs/triangles.md, "The cpu's
packets: a mesh's are 8x8".
"""

import hashlib
import json
import statistics
import sys
import time

import numpy as np

import raybench
from raybench import Camera
from raybench.bench import meshes
from raybench.mesh_render import mesh_scene
from raybench.meshes import Mesh

# The view of `peers.py embreex`: the icosphere from (0, 0, -3).
CAMERA = Camera(position=(0.0, 0.0, -3.0), look_at=(0.0, 0.0, 0.0), fov_deg=60.0)


def timed(scene, frames: int, shading: str = "thesis", camera=CAMERA) -> dict:
    """The scene's cpu frames at 1680x1050 on 2 threads from `camera`: the
    median of `frames` warm frames of wall time (ms), and hashes of the first
    frame's picture and hits."""
    with raybench.Renderer(scene, 1680, 1050, device="cpu", threads=2, shading=shading) as renderer:
        first = renderer.render(camera)
        times = []
        for _ in range(frames):
            start = time.perf_counter()
            renderer.render(camera)
            times.append((time.perf_counter() - start) * 1e3)
    image, hits = (hashlib.sha1(bytes(a)).hexdigest()[:12] for a in (first.image, first.hits))
    return {"frame_ms": round(statistics.median(times), 2), "image": image, "hits": hits}


def shuffled(mesh):
    """The mesh with its faces in a seeded random order: the same triangles, none near the one
    before it in memory (a file's order is most often near its order in space)."""
    order = np.random.default_rng(1).permutation(len(mesh.faces))
    return Mesh(mesh.vertices, np.ascontiguousarray(mesh.faces[order]), mesh.normals)


def main(frames: int, subdivisions: list[int], shuffle: bool = False, shading: str = "thesis") -> None:
    def mesh(k):
        made = meshes.icosphere(20 * 4**k)
        return shuffled(made) if shuffle else made

    out = {20 * 4**k: timed(mesh_scene(mesh(k)), frames, shading) for k in subdivisions}
    print(json.dumps({"raybench": raybench.__file__, "shuffled": shuffle, "shading": shading, "frames": out}))


if __name__ == "__main__":
    flags = {a for a in sys.argv[1:] if a.startswith("--")}
    numbers = [int(a) for a in sys.argv[1:] if not a.startswith("--")]
    main(numbers[0], numbers[1:] or [6, 8], "--shuffled" in flags, "whitted" if "--whitted" in flags else "thesis")
