"""What the scene's key costs a cluster frame (issue 17). raybench.cluster names a scene on the
workers by Dask's hash of it (`tokenize`), computed for every frame, so that an array changed in
place is never taken for the old scene. Dask hashes an array's bytes with the fastest hasher it
can import: xxhash (a raybench dependency), else SHA-1. Here each hasher that Dask found times
`tokenize(scene)`, the hashers taken in turn round after round so that a busy machine's noise
falls on all of them alike. One record of the results schema's "parts" suite (quantity
"scene-key") a sphere count and hasher.

    PYTHONPATH=src:benchmarks python benchmarks/archive/scene_key.py --spheres 1000 --spheres 100000 \\
        --spheres 1000000 --rounds 11
"""

from __future__ import annotations

import argparse
import sys

import _harness
import dask.hashing
from dask.base import tokenize

import raybench


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--spheres", type=int, action="append", help="sphere counts (repeat; default 100000)")
    _harness.add_common(parser, frames=1, rounds=11)
    args = parser.parse_args(argv)
    _harness.check_common(parser, args)
    found = list(dask.hashing.hashers)

    def keyed(hasher, scene):
        dask.hashing.hashers[:] = [hasher]  # tokenize takes the list's first
        return _harness.timings(lambda: tokenize(scene), 1)[0]

    settings = {"hashers": [h.__name__ for h in found]}
    try:
        with _harness.Records("scene_key", args, settings) as out:
            for n in args.spheres or [100_000]:
                scene = raybench.random_spheres(n, seed=0)
                variants = {h: (lambda h=h, s=scene: keyed(h, s)) for h in found}
                times = _harness.paired(variants, args.rounds * args.frames)
                for hasher in found:
                    out.write(
                        _harness.part(
                            "scene-key", "cpu", times[hasher], spheres=n, options={"hasher": hasher.__name__},
                            values={"bytes": scene.spheres.nbytes},
                        )
                    )  # fmt: skip
    finally:
        dask.hashing.hashers[:] = found
    return 0


if __name__ == "__main__":
    sys.exit(main())
