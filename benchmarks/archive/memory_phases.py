"""Where the cpu's memory peaks with a large mesh: the process's resident set polled every
millisecond while a frame of random triangles is made (mesh_build.memory's frame), its peak and
its last reading in each phase (the tracer's making, the tree's build, its 4-wide collapse, the
frame), over the mesh's own bytes. The mesh is handed over painted (meshes.Painted), as
mesh_build.memory hands it; before 2026-12-05 (later) the frame was made from its scene buffer.

    PYTHONPATH=src:benchmarks python benchmarks/archive/memory_phases.py 10000000
    PYTHONPATH=src:benchmarks python benchmarks/archive/memory_phases.py 5242880 icosphere
"""

import gc
import sys
import threading
import time

import _harness
import mesh_build
import psutil

from raybench import backends
from raybench import bvh as bvh_mod
from raybench.backends.cpu import tracer as cpu_tracer
from raybench.camera import Camera
from raybench.meshes import MESH_COLOUR, Painted

marks = []


def _marked(name, f):
    def call(*args, **kwargs):
        marks.append((time.perf_counter(), name))
        return f(*args, **kwargs)

    return call


def main() -> None:
    _harness.own_pages()  # the resident set counts every large array
    n = int(sys.argv[1])
    for name in ("build", "collapse"):
        setattr(bvh_mod, name, _marked(name, getattr(bvh_mod, name)))
    cpu_tracer.bvh_mod = bvh_mod
    width, height = mesh_build.SIZE
    basis = Camera(position=(0.0, 0.0, -3.0), look_at=(0.0, 0.0, 0.0), fov_deg=60.0).basis(width, height)
    kind = "icosphere" if len(sys.argv) > 2 and sys.argv[2] == "icosphere" else "random"
    mesh_build.warm_up("cpu", kind, basis)
    mesh = mesh_build.memory_mesh(n, kind)
    gc.collect()  # trimesh's cycles let go now, not in the frame's making (mesh_build.memory)
    own = mesh.vertices.nbytes + mesh.faces.nbytes
    process, line, stop = psutil.Process(), [], threading.Event()

    def poll():
        while not stop.wait(0.001):
            line.append((time.perf_counter(), process.memory_info().rss))

    before = process.memory_info().rss
    thread = threading.Thread(target=poll, daemon=True)
    thread.start()
    marks.append((time.perf_counter(), "tracer"))
    tracer = backends.tracer("cpu", Painted(mesh, MESH_COLOUR), width, height, primitive="triangle")
    marks.append((time.perf_counter(), "frame"))
    tracer.trace(basis)
    marks.append((time.perf_counter(), "end"))
    stop.set()
    thread.join()
    for (start, name), (end, _) in zip(marks, marks[1:]):
        part = [rss for t, rss in line if start <= t < end]
        if part:
            print(f"{name:16s} {end - start:6.2f} s  peak {(max(part) - before) / own:5.2f}x  "
                  f"last {(part[-1] - before) / own:5.2f}x")  # fmt: skip
    tracer.close()


if __name__ == "__main__":
    main()
