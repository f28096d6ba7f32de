"""What a CPU frame costs before its walk: every pixel's ray made, its packet's root test, its
colour and its stores. The same Tracer traces the view benchmarks/peers.py embree traces
and the same camera turned round, away from every sphere (each ray misses the root's boxes), in
turn, round after round; the second is the frame's fixed part, the floor of any frame of that
size on this machine. Two records of the results schema's "parts" suite a layout and sphere
count: quantity "cpu-frame" (the whole frame) and "cpu-frame-fixed" (the fixed part, with its
share of the frame).

    PYTHONPATH=src:benchmarks python benchmarks/archive/cpu_fixed_cost.py --spheres 1000 --spheres 10000 \\
        --spheres 100000 --rounds 9
"""

from __future__ import annotations

import argparse
import sys

import _harness

import raybench
from raybench import Camera, backends
from raybench.backends.cpu import default_threads
from raybench.scene import SPREADS


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--spheres", type=int, action="append", help="sphere counts (repeat; default 1000)")
    parser.add_argument("--layout", action="append", choices=SPREADS, help="layouts (repeat; default all)")
    parser.add_argument("--size", default="1680x1050")
    _harness.add_common(parser, frames=2, rounds=9)
    args = parser.parse_args(argv)
    _harness.check_common(parser, args)
    width, height = (int(v) for v in args.size.lower().split("x"))
    threads = default_threads()
    with _harness.Records("cpu_fixed_cost", args, {"threads": threads}) as out:
        for n in args.spheres or [1000]:
            for layout in args.layout or SPREADS:
                scene = raybench.random_spheres(n, seed=0, layout=layout)
                # The view benchmarks/peers.py embree traces, and the same camera turned round.
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
                    variants = {name: (lambda b=basis, t=tracer: _harness.timings(lambda: t.trace(b), args.frames))
                                for name, basis in views.items()}  # fmt: skip
                    times = _harness.paired(variants, args.rounds)
                finally:
                    tracer.close()
                share = _harness.median(times["fixed"]) / _harness.median(times["frame"])
                for name, quantity in (("frame", "cpu-frame"), ("fixed", "cpu-frame-fixed")):
                    out.write(
                        _harness.part(
                            quantity, "cpu", times[name], spheres=n, width=width, height=height,
                            options={"layout": layout, "threads": threads, "accel": "bvh"},
                            values={"fixed_share": round(share, 3)} if name == "fixed" else None,
                        )
                    )  # fmt: skip
    return 0


if __name__ == "__main__":
    sys.exit(main())
