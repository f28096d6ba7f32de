"""What a CPU frame costs before its walk: every pixel's ray made, its
packet's root test, its colour and its stores. The same Tracer traces the
view benchmarks/embree_side_by_side.py traces and the same camera turned
round, away from every sphere (each ray misses the root's boxes), in turn,
round after round; the second is the frame's fixed part, the floor of any
frame of that size on this machine.
One line of JSON a layout and sphere count: the medians in ms, and the
fixed part's share of the frame.

    PYTHONPATH=src python benchmarks/cpu_fixed_cost.py --spheres 1000 --spheres 10000 --spheres 100000 --rounds 9
"""

from __future__ import annotations

import argparse
import json
import statistics
import sys
import time

import raybench
from raybench import Camera, backends, machine
from raybench.backends.cpu import default_threads
from raybench.scene import SPREADS


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--spheres", type=int, action="append", help="sphere counts (repeat; default 1000)")
    parser.add_argument("--layout", action="append", choices=SPREADS, help="layouts (repeat; default all)")
    parser.add_argument("--size", default="1680x1050")
    parser.add_argument("--rounds", type=int, default=9)
    parser.add_argument("--frames", type=int, default=2, help="frames a view in each round")
    args = parser.parse_args(argv)
    width, height = (int(v) for v in args.size.lower().split("x"))
    print(json.dumps({"what": "run", "git_commit": machine.git_commit(), "machine": machine.describe()["cpu"],
                      "threads": default_threads()}), flush=True)  # fmt: skip
    for n in args.spheres or [1000]:
        for layout in args.layout or SPREADS:
            scene = raybench.random_spheres(n, seed=0, layout=layout)
            # The view benchmarks/embree_side_by_side.py traces, and the same camera turned round.
            views = {"frame": Camera(), "fixed": Camera(look_at=(0.0, 0.0, -1.0))}
            views = {name: camera.basis(width, height) for name, camera in views.items()}
            tracer = backends.tracer("cpu", scene.spheres, width, height, accel="bvh")
            try:
                for basis in views.values():  # compiled, warm
                    tracer.trace(basis)
                    tracer.trace(basis)
                _, hits = tracer.trace(views["fixed"])
                if (hits >= 0).any():
                    raise SystemExit(f"{layout} {n}: the view turned away still sees a sphere")
                times: dict[str, list[float]] = {name: [] for name in views}
                for _ in range(args.rounds):
                    for name, basis in views.items():
                        for _ in range(args.frames):
                            start = time.perf_counter()
                            tracer.trace(basis)
                            times[name].append(time.perf_counter() - start)
            finally:
                tracer.close()
            frame, fixed = (statistics.median(times[name]) * 1e3 for name in ("frame", "fixed"))
            print(json.dumps({"spheres": n, "layout": layout, "width": width, "height": height,
                              "frame_ms": round(frame, 2), "fixed_ms": round(fixed, 2),
                              "fixed_share": round(fixed / frame, 3), "rounds": args.rounds,
                              "frames": args.frames}), flush=True)  # fmt: skip
    return 0


if __name__ == "__main__":
    sys.exit(main())
