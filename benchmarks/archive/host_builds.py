"""The host's tree for the cpu: the build (bvh.build) and its 4-wide collapse (bvh.collapse),
medians of --repeats, over random triangles (mesh_build's, 48 bytes each in the scene's
buffer), random spheres and, with --icosphere K, the meshes suite's icosphere of 20 x 4^K
triangles built from the mesh itself for the cpu's packets (as the tracer builds a painted
mesh). One version a process: run it under each version's src/ in turn.

    PYTHONPATH=<its src>:benchmarks python benchmarks/archive/host_builds.py NAME
    ... host_builds.py NAME --triangles 0 --spheres 10000 --spheres 1000000 --icosphere 9 --repeats 7
"""

import argparse
import json
import time

import mesh_build
import numpy as np

import raybench
from raybench import bvh
from raybench.kernels.primitives import sphere, triangle, triangle_mesh
from raybench.layout import NODE_COST
from raybench.meshes import MESH_COLOUR, mesh_leaves


def _first(items, n: int):
    """The first n primitives, enough to compile the builder's ways for the kind."""
    if isinstance(items, tuple):
        return triangle_mesh.first(items, n)
    return np.ascontiguousarray(items[:, :n])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("name", help="the version's name in the output line")
    parser.add_argument("--triangles", type=int, default=10_000_000)
    parser.add_argument("--spheres", type=int, action="append", help="default: 1,000,000")
    parser.add_argument("--icosphere", type=int, default=0, help="its subdivisions (default: none)")
    parser.add_argument("--threads", type=int, default=2)
    parser.add_argument("--repeats", type=int, default=5)
    args = parser.parse_args()
    out = {}
    scenes = [(f"spheres {n}", raybench.random_spheres(n, seed=0).spheres, sphere) for n in args.spheres or [1_000_000]]
    if args.triangles:
        leaves = mesh_leaves(mesh_build.random_triangles(args.triangles), MESH_COLOUR)
        scenes.insert(0, (f"triangles {args.triangles}", leaves, triangle))
    if args.icosphere:
        mesh = mesh_build.icosphere(args.icosphere)
        scenes.append((f"icosphere {len(mesh)}", (mesh.vertices, mesh.faces), triangle_mesh))
    for name, items, kind in scenes:
        cost = triangle.PACKETS_NODE_COST if kind is triangle_mesh else NODE_COST
        bvh.build(_first(items, 200_000), threads=args.threads, primitive=kind, node_cost=cost)  # compiled
        builds, collapses = [], []
        for _ in range(args.repeats):
            start = time.perf_counter()
            tree = bvh.build(items, threads=args.threads, primitive=kind, node_cost=cost)
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
