"""The host's tree for the cpu: the build (bvh.build) and its 4-wide collapse (bvh.collapse),
medians of --repeats, over random triangles (mesh_build's, 48 bytes each in the scene's
buffer) and random spheres. One version a process: run it under each version's src/ in turn.

    PYTHONPATH=<its src>:benchmarks python benchmarks/archive/host_builds.py NAME
"""

import argparse
import json
import time

import mesh_build
import numpy as np

import raybench
from raybench import bvh
from raybench.kernels.primitives import sphere, triangle
from raybench.meshes import MESH_COLOUR, mesh_leaves


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("name", help="the version's name in the output line")
    parser.add_argument("--triangles", type=int, default=10_000_000)
    parser.add_argument("--spheres", type=int, default=1_000_000)
    parser.add_argument("--threads", type=int, default=2)
    parser.add_argument("--repeats", type=int, default=5)
    args = parser.parse_args()
    out = {}
    scenes = (
        (
            f"triangles {args.triangles}",
            mesh_leaves(mesh_build.random_triangles(args.triangles), MESH_COLOUR),
            triangle,
        ),
        (f"spheres {args.spheres}", raybench.random_spheres(args.spheres, seed=0).spheres, sphere),
    )
    for name, items, kind in scenes:
        bvh.build(np.ascontiguousarray(items[:, :200_000]), threads=args.threads, primitive=kind)  # compiled
        builds, collapses = [], []
        for _ in range(args.repeats):
            start = time.perf_counter()
            tree = bvh.build(items, threads=args.threads, primitive=kind)
            built = time.perf_counter()
            wide = bvh.collapse(tree)
            builds.append((built - start) * 1e3)
            collapses.append((time.perf_counter() - built) * 1e3)
            del tree, wide
        out[name] = {
            "build_ms": round(float(np.median(builds)), 1),
            "collapse_ms": round(float(np.median(collapses)), 1),
        }
    print(args.name, json.dumps(out))


if __name__ == "__main__":
    main()
