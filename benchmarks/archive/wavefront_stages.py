"""Where a cuda wavefront frame's time goes: each stage of each wave timed by CUDA events
(Wavefront.mark), summed by stage, medians over frames; and the frame's kernel time with each
grid a stage may run on (--wave-grid: blocks of 128 threads; 0 for the default), the grids
taking turns frame by frame. The issue's scene: random_spheres(n, materials=True), depth 5,
4 shadow samples, 1680x1050 by default. Records of the results schema's "parts" suite: the
frame's kernel time a grid (quantity "wavefront-kernel", option wave_grid, the frame's rays by
kind as figures) and each stage's time a frame ("wavefront-stage-" and the stage). Needs a CUDA GPU.
"""

import argparse
import re
import sys

import _harness
from numba import cuda

import raybench
from raybench import Camera, backends, lighting


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--spheres", type=int, action="append")
    parser.add_argument("--size", default="1680x1050")
    parser.add_argument("--depth", type=int, default=5)
    parser.add_argument("--shadow-samples", type=int, default=4)
    parser.add_argument("--wave-grid", type=int, action="append", help="blocks a stage (0: the default)")
    _harness.add_common(parser, frames=7)
    args = parser.parse_args()
    _harness.check_common(parser, args)
    width, height = (int(v) for v in args.size.split("x"))
    settings = {"depth": args.depth, "shadow_samples": args.shadow_samples}
    with _harness.Records("wavefront_stages", args, settings) as out:
        for n in args.spheres or [1000, 10_000, 100_000]:
            measure(out, n, width, height, args)
    return 0


def measure(out, n: int, width: int, height: int, args) -> None:
    scene = raybench.random_spheres(n, seed=0, materials=True)
    shading = lighting.Shading.of(scene, args.depth, args.shadow_samples)
    basis = Camera().basis(width, height)
    grids = args.wave_grid or [0]
    tracers = {
        g: backends.tracer("cuda", scene.spheres, width, height, whitted=shading, wave_grid=g or None) for g in grids
    }
    for tracer in tracers.values():
        tracer.trace(basis)  # compiled, queues grown
    kernel = _harness.paired({g: (lambda t=t: t.timed_trace(basis)) for g, t in tracers.items()},
                             args.frames * args.rounds)  # fmt: skip
    stages = {}
    tracer = tracers[grids[0]]
    for _ in range(args.frames * args.rounds):
        marks = []

        def mark(stage, marks=marks):
            event = cuda.event()
            event.record()
            marks.append((stage, event))

        tracer.wavefront.mark = mark
        start = cuda.event()
        start.record()
        tracer.trace(basis)
        tracer.wavefront.mark = None
        frame = {}
        previous = start
        for stage, event in marks:
            frame[stage] = frame.get(stage, 0.0) + previous.elapsed_time(event)
            previous = event
        for stage, ms in frame.items():
            stages.setdefault(stage, []).append(ms)
    rays = dict(zip(("primary", "shadow", "reflection", "refraction"), tracer.ray_counts.tolist()))
    fields = {"spheres": n, "width": width, "height": height}
    for g, times in kernel.items():
        out.write(_harness.part("wavefront-kernel", "cuda", times, options={"wave_grid": g}, values=rays, **fields))
    for stage, times in stages.items():
        quantity = "wavefront-stage-" + re.sub(r"[^A-Za-z0-9.-]+", "-", str(stage)).strip("-")
        out.write(_harness.part(quantity, "cuda", times, **fields))
    for tracer in tracers.values():
        tracer.close()


if __name__ == "__main__":
    sys.exit(main())
