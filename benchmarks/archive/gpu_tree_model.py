"""The GPU's trees (each quality) built by raybench.bvh.lbvh_model, the CPU model of the GPU
builder's kernels (bit for bit the simulator's): their SAH cost against the host's binned SAH
tree (raybench.bvh) at sizes the simulator cannot build, on a machine with no GPU. One record of
the results schema's "parts" suite (quantity "gpu-tree-model": the model's build time, with the
SAH costs, depths and rows of both trees) per sphere count and quality.

    PYTHONPATH=benchmarks python benchmarks/archive/gpu_tree_model.py [--spheres 1000 --spheres 100000] \\
        [--quality sah --quality treelet]
"""

from __future__ import annotations

import argparse
import sys

import _harness

import raybench
from raybench import bvh
from raybench.bvh import cost as tree_cost
from raybench.bvh import lbvh_model


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--spheres", action="append", type=int, help="default: 1000, 100000, 1000000")
    parser.add_argument("--quality", action="append", choices=lbvh_model.QUALITIES, help="default: all")
    parser.add_argument("--treelet-passes", type=int, default=None, help="bottom-up passes of treelets (default 1)")
    _harness.add_common(parser, frames=1)
    args = parser.parse_args()
    _harness.check_common(parser, args)
    settings = {"treelet_passes": args.treelet_passes}
    with _harness.Records("gpu_tree_model", args, settings) as out:
        for n in args.spheres or [1000, 100_000, 1_000_000]:
            spheres = raybench.random_spheres(n, seed=0).spheres
            host = bvh.build(spheres)
            host_sah = tree_cost.sah_cost(host.nodes)
            for quality in args.quality or ["lbvh", "sah", "treelet"]:  # cheapest first
                built = []

                def model(q=quality, s=spheres, into=built):
                    into.append(lbvh_model.build(s, q, passes=args.treelet_passes))

                times = _harness.timings(model, args.frames)
                nodes, _order, _ordered, depth, rows, cost = built[-1]
                sah = tree_cost.sah_cost(nodes)
                values = {
                    "sah": round(sah, 3), "sah_device_sum": round(cost, 3), "host_sah": round(host_sah, 3),
                    "sah_over_host": round(sah / host_sah, 4), "depth": depth, "host_depth": host.depth,
                    "rows_reached": rows, "host_rows": host.node_count,
                }  # fmt: skip
                out.write(_harness.part("gpu-tree-model", "cpu", times, spheres=n, options={"quality": quality},
                                        values=values))  # fmt: skip
    return 0


if __name__ == "__main__":
    sys.exit(main())
