"""The BVH build's time, one line of JSON per (spheres, threads): the median
of --repeats builds of random_spheres (compiled code only, as raybench bench
reports it), the tree's size, and which raybench ran.

For A/B runs of two versions on one machine, side by side: run it once per
version's source tree, alternating, e.g.

    PYTHONPATH=old/src python benchmarks/bvh_build.py --threads 16
    PYTHONPATH=src     python benchmarks/bvh_build.py --threads 16
"""

import argparse
import json
import os
import statistics
import sys

import raybench
from raybench import bvh

SIZES = {"1k": 1000, "10k": 10_000, "100k": 100_000, "1M": 1_000_000, "3M": 3_000_000}


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--size", action="append", choices=list(SIZES), help="default: 100k and 1M")
    parser.add_argument("--threads", action="append", type=int, help="default: every core")
    parser.add_argument("--repeats", type=int, default=7)
    args = parser.parse_args()
    if args.repeats < 1:
        parser.error(f"--repeats: must be at least 1, got {args.repeats}")
    if any(t < 1 for t in args.threads or []):
        parser.error("--threads: must be at least 1")
    bvh.compile_builder()
    for size in args.size or ["100k", "1M"]:
        spheres = raybench.random_spheres(SIZES[size], seed=0).spheres
        for threads in args.threads or [os.cpu_count() or 1]:
            times = [bvh.build(spheres, threads=threads, _timed=False).build_s * 1e3 for _ in range(args.repeats)]
            tree = bvh.build(spheres, threads=threads, _timed=False)
            print(
                json.dumps(
                    {
                        "spheres": SIZES[size],
                        "threads": threads,
                        "repeats": args.repeats,
                        "median_ms": round(statistics.median(times), 2),
                        "min_ms": round(min(times), 2),
                        "nodes": tree.node_count,
                        "depth": tree.depth,
                        "cores": os.cpu_count(),
                        "raybench": raybench.__file__,
                    }
                ),
                flush=True,
            )
    return 0


if __name__ == "__main__":
    sys.exit(main())
