"""What a dense mesh's cpu frame costs with the mesh out of sight: the meshes suite's icosphere
of 20 * 4^K triangles at 1680x1050, primary rays through the packets, all cores, seen from
(0, 0, -3) facing it and turned away from it (looking at (0, 0, -6)), the two views in turn,
three rounds of the median of 9 warm frames of wall time. Turned away, no packet enters the
root's box, so the frame is the rays' making and the misses' colouring alone; the difference is
the walk and the leaves. The figures: docs/triangles.md, "The cpu's packets: a triangle meets
the rows it covers".

    PYTHONPATH=src:benchmarks python benchmarks/archive/mesh_out_of_sight.py 8
"""

import statistics
import sys
import time

from _embreex import icosphere

from raybench import backends
from raybench.camera import Camera
from raybench.meshes import MESH_COLOUR, mesh_leaves

SIZE = (1680, 1050)
VIEWS = {
    "facing": Camera(position=(0, 0, -3), look_at=(0, 0, 0), fov_deg=60),
    "away": Camera(position=(0, 0, -3), look_at=(0, 0, -6), fov_deg=60),
}


def main(subdivisions: int) -> None:
    width, height = SIZE
    leaves = mesh_leaves(icosphere(subdivisions), MESH_COLOUR)
    with backends.tracer("cpu", leaves, width, height, primitive="triangle") as tracer:
        tracer.compile()
        for _ in range(3):
            for name, camera in VIEWS.items():
                basis = camera.basis(width, height)
                tracer.trace(basis)
                times = []
                for _ in range(9):
                    start = time.perf_counter()
                    tracer.trace(basis)
                    times.append(time.perf_counter() - start)
                hit = float((tracer.hits >= 0).mean())
                print(f"{name}: {statistics.median(times) * 1e3:.1f} ms, {hit:.1%} of pixels hit")


if __name__ == "__main__":
    main(int(sys.argv[1]))
