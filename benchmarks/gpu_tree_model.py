"""The GPU's trees (each quality) built by raybench.bvh.lbvh_model, the CPU model of the GPU
builder's kernels (bit for bit the simulator's): their SAH cost against the host's binned SAH
tree (raybench.bvh) at sizes the simulator cannot build, on a machine with no GPU.

    python benchmarks/gpu_tree_model.py [--spheres 1000 --spheres 100000] [--quality sah --quality treelet]

prints, per sphere count and quality, the SAH cost of the model's tree over the host's, as one
JSON line each.
"""

from __future__ import annotations

import argparse
import json
import sys
import time

import raybench
from raybench import bvh
from raybench.bvh import cost as tree_cost
from raybench.bvh import lbvh_model


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--spheres", action="append", type=int, help="default: 1000, 100000, 1000000")
    parser.add_argument("--quality", action="append", choices=lbvh_model.QUALITIES, help="default: all")
    parser.add_argument("--treelet-passes", type=int, default=None, help="bottom-up passes of treelets (default 1)")
    args = parser.parse_args()
    for n in args.spheres or [1000, 100_000, 1_000_000]:
        spheres = raybench.random_spheres(n, seed=0).spheres
        host = bvh.build(spheres)
        host_sah = tree_cost.sah_cost(host.nodes)
        for quality in args.quality or ["lbvh", "sah", "treelet"]:  # cheapest first
            start = time.perf_counter()
            nodes, _order, _ordered, depth, rows, cost = lbvh_model.build(spheres, quality, passes=args.treelet_passes)
            seconds = time.perf_counter() - start
            sah = tree_cost.sah_cost(nodes)
            row = {
                "spheres": n,
                "quality": quality,
                "sah": round(sah, 3),
                "sah_device_sum": round(cost, 3),
                "host_sah": round(host_sah, 3),
                "sah_over_host": round(sah / host_sah, 4),
                "depth": depth,
                "host_depth": host.depth,
                "rows_reached": rows,
                "host_rows": host.node_count,
                "model_s": round(seconds, 2),
            }
            print(json.dumps(row), flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
