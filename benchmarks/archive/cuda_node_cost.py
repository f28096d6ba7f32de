"""What the SAH's node cost in the host's tree that cuda walks buys a mesh: for each cost given,
in turn and for as many rounds, the device memory of a frame of N random triangles
(mesh_build.memory: NVML's used memory beyond what the process held with the mesh made) and the
meshes' frames (mesh_frames_gpu: kernels' and whole frames' medians, the pictures' hashes, which
must not change with the tree). The cost is the triangle kind's CUDA_NODE_COST, set in this
process before each tracer is made (the tracer reads it at its build). One JSON line a cost and
round.

    PYTHONPATH=src:benchmarks:benchmarks/archive python benchmarks/archive/cuda_node_cost.py \\
        --cost 2 4 6 --rounds 2 --memory 10000000 --icosphere 1310720 --random 1000000 --frames 5

The figures: docs/triangles.md#memory.
"""

import argparse
import gc
import json

import mesh_build
import mesh_frames_gpu
import numpy as np
from numba import cuda

from raybench.bench import meshes
from raybench.kernels.primitives import KINDS


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--cost", type=float, nargs="+", required=True)
    parser.add_argument("--rounds", type=int, default=2)
    parser.add_argument("--memory", type=int, default=10_000_000, help="random triangles (0: no memory frame)")
    parser.add_argument("--icosphere", type=int, nargs="*", default=[1_310_720])
    parser.add_argument("--random", type=int, nargs="*", default=[1_000_000])
    parser.add_argument("--frames", type=int, default=5)
    args = parser.parse_args()
    triangle = KINDS["triangle"]
    points = [("icosphere", n) for n in args.icosphere] + [("random", n) for n in args.random]
    scenes = {f"{kind} {n}": meshes.mesh_scene(kind, n) for kind, n in points}
    for r in range(args.rounds):
        costs = args.cost if r % 2 == 0 else args.cost[::-1]
        for cost in costs:
            triangle.CUDA_NODE_COST = np.float32(cost)
            line = {"cost": cost, "round": r, "frames": {}}
            for name, scene in scenes.items():
                for shading in ("thesis", "whitted"):
                    line["frames"][f"{name} {shading}"] = mesh_frames_gpu._frames(scene, "cuda", shading, args.frames)
            if args.memory:
                gc.collect()
                cuda.current_context().deallocations.clear()  # the frames' arrays freed before the count
                part = mesh_build.memory(args.memory, "cuda", 2)
                line["memory"] = part.get("values", part)
            print(json.dumps(line), flush=True)


if __name__ == "__main__":
    main()
