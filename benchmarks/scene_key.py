"""What the scene's key costs a cluster frame (issue 17). raybench.cluster
names a scene on the workers by Dask's hash of it (`tokenize`), computed
for every frame, so that an array changed in place is never taken for the
old scene. Dask hashes an array's bytes with the fastest hasher it can
import: xxhash (a raybench dependency), else SHA-1. Here each hasher that
Dask found times `tokenize(scene)`, the hashers taken in turn round after
round so that a busy machine's noise falls on all of them alike. One line
of JSON a sphere count and hasher: the median and fastest in ms.

    PYTHONPATH=src python benchmarks/scene_key.py --spheres 1000 --spheres 100000 --spheres 1000000 --rounds 11
"""

from __future__ import annotations

import argparse
import json
import statistics
import sys
import time

import dask.hashing
from dask.base import tokenize

import raybench
from raybench import machine


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--spheres", type=int, action="append", help="sphere counts (repeat; default 100000)")
    parser.add_argument("--rounds", type=int, default=11)
    args = parser.parse_args(argv)
    found = list(dask.hashing.hashers)
    print(json.dumps({"what": "run", "git_commit": machine.git_commit(), "machine": machine.describe()["cpu"],
                      "hashers": [h.__name__ for h in found]}), flush=True)  # fmt: skip
    try:
        for n in args.spheres or [100_000]:
            scene = raybench.random_spheres(n, seed=0)
            times: dict = {h: [] for h in found}
            for _ in range(args.rounds):
                for hasher in found:
                    dask.hashing.hashers[:] = [hasher]  # tokenize takes the list's first
                    start = time.perf_counter()
                    tokenize(scene)
                    times[hasher].append(time.perf_counter() - start)
            for hasher in found:
                print(json.dumps({"spheres": n, "bytes": scene.spheres.nbytes, "hasher": hasher.__name__,
                                  "median_ms": round(statistics.median(times[hasher]) * 1e3, 3),
                                  "fastest_ms": round(min(times[hasher]) * 1e3, 3), "rounds": args.rounds}),
                      flush=True)  # fmt: skip
    finally:
        dask.hashing.hashers[:] = found
    return 0


if __name__ == "__main__":
    sys.exit(main())
