"""The BVH build's time: one record of the results schema's "parts" suite (quantity
"bvh-build") per (spheres, threads), the --frames builds of random_spheres (compiled code only,
as raybench bench reports it) with the tree's size and depth. `raybench report` reads them.

For A/B runs of two versions on one machine, side by side: run it once per version's source
tree, alternating, each with its own --label, e.g.

    PYTHONPATH=old/src python benchmarks/bvh_build.py --threads 16 --label old --out builds.jsonl
    PYTHONPATH=src     python benchmarks/bvh_build.py --threads 16 --label new --out builds.jsonl
"""

import argparse
import sys

import _harness

import raybench
from raybench import bvh
from raybench.host import usable_cores

SIZES = {"1k": 1000, "10k": 10_000, "100k": 100_000, "1M": 1_000_000, "3M": 3_000_000}


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--size", action="append", choices=list(SIZES), help="default: 100k and 1M")
    parser.add_argument("--threads", action="append", type=int, help="default: every core")
    _harness.add_common(parser, frames=7)
    args = parser.parse_args()
    _harness.check_common(parser, args)
    if any(t < 1 for t in args.threads or []):
        parser.error("--threads: must be at least 1")
    bvh.compile_builder()
    with _harness.Records("bvh_build", args, {"size": args.size, "threads": args.threads}) as out:
        for _ in range(args.rounds):
            for size in args.size or ["100k", "1M"]:
                spheres = raybench.random_spheres(SIZES[size], seed=0).spheres
                for threads in args.threads or [usable_cores()]:
                    times = [bvh.build(spheres, threads=threads).build_s * 1e3 for _ in range(args.frames)]
                    tree = bvh.build(spheres, threads=threads)
                    out.write(
                        _harness.part(
                            "bvh-build", "cpu", times, spheres=SIZES[size], options={"threads": threads},
                            values={"nodes": tree.node_count, "depth": tree.depth},
                        )
                    )  # fmt: skip
    return 0


if __name__ == "__main__":
    sys.exit(main())
