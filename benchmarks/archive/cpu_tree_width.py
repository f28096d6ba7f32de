"""The CPU's packet walk on the binary SAH tree against the same tree collapsed into 4-wide
nodes (the cpu Tracer's tree_width, issue 16 item 6), side by side in one process: a Tracer of
each over the same scene, warm frames, then --rounds rounds of --frames frames each, the two
alternating which goes first each round (a shared machine's load falls on both). One record of
the results schema (suite "scaling", accel "bvh", option tree_width) per (layout, spheres, tree
width), with whether both gave the same picture; `raybench report` reads them.

    PYTHONPATH=src:benchmarks python benchmarks/archive/cpu_tree_width.py --spheres 1000 10000 100000 1000000
"""

import argparse
import sys

import _harness
import numpy as np

import raybench
from raybench import Camera, backends
from raybench.scene import SPREADS


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--spheres", type=int, nargs="+", default=[1000, 10_000, 100_000, 1_000_000])
    p.add_argument("--layouts", nargs="+", default=["even"], choices=SPREADS)
    p.add_argument("--size", default="1680x1050")
    p.add_argument("--threads", type=int, default=None)
    _harness.add_common(p, frames=2, rounds=5)
    args = p.parse_args()
    _harness.check_common(p, args)
    width, height = (int(v) for v in args.size.split("x"))
    basis = Camera().basis(width, height)
    settings = {"spheres": args.spheres, "layouts": args.layouts, "threads": args.threads}
    with _harness.Records("cpu_tree_width", args, settings) as out:
        for n in args.spheres:
            for layout in args.layouts:
                scene = raybench.random_spheres(n, 0, layout=layout)
                tracers = {}
                try:
                    for w in (2, 4):
                        tracers[w] = backends.tracer(
                            "cpu", scene.spheres, width, height, threads=args.threads, tree_width=w
                        )
                        tracers[w].compile()
                        for _ in range(2):
                            tracers[w].trace(basis)
                    same = np.array_equal(tracers[2].hits, tracers[4].hits) and np.array_equal(
                        tracers[2].image, tracers[4].image
                    )
                    variants = {w: (lambda t=t: _harness.timings(lambda: t.trace(basis), args.frames))
                                for w, t in tracers.items()}  # fmt: skip
                    times = _harness.paired(variants, args.rounds)
                finally:
                    for t in tracers.values():
                        t.close()
                for w, t in tracers.items():
                    options = {"accel": "bvh", "threads": t.threads, "tree_width": w}
                    if layout != "even":
                        options["layout"] = layout
                    record = _harness.point("scaling", "cpu", width, height, n, options, times[w], build_s=t.build_s)
                    record["same_picture"] = bool(same)
                    out.write(record)
    return 0


if __name__ == "__main__":
    sys.exit(main())
