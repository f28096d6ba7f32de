"""A large mesh's memory on the cpu through a user's path: a Scene of the mesh, raybench.Renderer
on the cpu and one frame, the peak resident set (the 1 ms poll and the kernel's VmHWM, as
mesh_build.memory takes it) beyond the process with the mesh made, over the mesh's own bytes.
mesh_build.memory hands the tracer the mesh directly; this is the same frame as `raybench render`
makes it. A version's src and its benchmarks/ first on PYTHONPATH (its mesh_build's Peak):

    PYTHONPATH=src:benchmarks python benchmarks/archive/scene_memory.py 10000000
"""

import gc
import json
import sys

from mesh_build import SIZE, Peak, _rss, random_triangles

from raybench import Camera, Renderer, Scene
from raybench.meshes import MESH_COLOUR
from raybench.scene_meshes import SceneMesh

CAMERA = Camera(position=(0.0, 0.0, -3.0), look_at=(0.0, 0.0, 0.0), fov_deg=60.0)


def frame(mesh) -> None:
    """The mesh's Scene, its cpu Renderer and one frame at mesh_build.SIZE."""
    scene = Scene([], [], [], meshes=[SceneMesh(mesh, MESH_COLOUR)])
    with Renderer(scene, *SIZE, device="cpu") as renderer:
        renderer.render(CAMERA)


def main(n: int) -> None:
    frame(random_triangles(8192))  # compiled or loaded first, the builder's way for many too
    mesh = random_triangles(n)
    own = mesh.vertices.nbytes + mesh.faces.nbytes
    gc.collect()
    before = _rss()
    with Peak(_rss, high_water=True) as peak:
        frame(mesh)
    extra = peak.peak - before
    record = {"triangles": n, "mesh_bytes": own, "peak_extra_bytes": extra, "over_mesh": round(extra / own, 3)}
    print(json.dumps(record))


if __name__ == "__main__":
    main(int(sys.argv[1]))
