"""Render one scene on every device present and compare: identical hit indices, colour
differences, and warm frame times. A quick check, not the benchmark: `raybench bench` measures
properly. One record of the results schema (suite "scaling", each device's default accel) per
device, the frames taken in turn device by device; with cuda present, its record carries the
comparison with the CPU's frame (where the hits differ, whether float32 rounding alone decides
there, by the float64 reference in tests/reference.py).

    PYTHONPATH=benchmarks python benchmarks/archive/compare_devices.py --spheres 1000 --size 1680x1050 --frames 20
"""

import argparse
import sys
from pathlib import Path

import _harness
import numpy as np

from raybench import Camera, backends, random_spheres
from raybench.cli import parse_size


def comparison(scene, width, height, cpu, cuda) -> dict:
    (ci, ch), (gi, gh) = cpu, cuda
    diff = np.abs(ci.astype(int) - gi.astype(int)).max(axis=2)
    out = {
        "hits_differ": int((ch != gh).sum()),
        "colour_differs": int((diff > 0).sum()),
        "max_colour_steps": int(diff.max()),
        "colour_differs_by_more_than_1_step": int((diff > 1).sum()),
    }
    # Where the devices disagree on the sphere, ask the float64 reference
    # whether rounding alone can decide it there.
    sys.path.insert(0, str(Path(__file__).resolve().parent.parent.parent / "tests"))
    from reference import trace

    differ = np.flatnonzero(ch != gh)
    ref = trace(scene, Camera(), width, height, pixels=differ)
    explained = [
        bool(ref.ambiguous[i]) and {int(ch.flat[p]), int(gh.flat[p])} <= ref.candidates.get(i, set())
        for i, p in enumerate(differ)
    ]
    out["hits_differ_where_float32_rounding_decides"] = int(sum(explained))
    return out


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--spheres", type=int, default=1000)
    ap.add_argument("--size", default="1680x1050")
    _harness.add_common(ap, frames=20)
    args = ap.parse_args()
    _harness.check_common(ap, args)
    width, height = parse_size(args.size)
    scene = random_spheres(args.spheres, 0)
    basis = Camera().basis(width, height)
    tracers, frames, first = {}, {}, {}
    try:
        for device in backends.present():
            tracers[device] = tracer = backends.tracer(device, scene.spheres, width, height)
            first[device] = _harness.timings(lambda t=tracer: t.trace(basis), 1)[0] / 1e3
            frames[device] = tuple(a.copy() for a in (tracer.image, tracer.hits))
        variants = {d: (lambda t=t: _harness.timings(lambda: t.trace(basis), args.frames)) for d, t in tracers.items()}
        times = _harness.paired(variants, args.rounds)
        with _harness.Records("compare_devices", args, {"spheres": args.spheres}) as out:
            for device, tracer in tracers.items():
                options = {"accel": tracer.accel}
                record = _harness.point(
                    "scaling", device, width, height, args.spheres, options, times[device],
                    first_frame_s=first[device], build_s=tracer.build_s,
                )  # fmt: skip
                if device == "cuda":
                    record["comparison_with_cpu"] = comparison(scene, width, height, frames["cpu"], frames["cuda"])
                out.write(record)
    finally:
        for tracer in tracers.values():
            tracer.close()
    return 0


if __name__ == "__main__":
    sys.exit(main())
