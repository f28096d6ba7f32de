"""Where a cuda wavefront frame's time goes: each stage of each wave timed by CUDA events
(Wavefront.mark), summed by stage, medians over frames; and the frame's kernel time with each
grid a stage may run on (--wave-grid: blocks of 128 threads; 0 for the default), the grids
taking turns frame by frame. The issue's scene: random_spheres(n, materials=True), depth 5,
4 shadow samples, 1680x1050 by default. Needs a CUDA GPU.
"""

import argparse
import json
import statistics
import sys

from numba import cuda

import raybench
from raybench import Camera, backends, lighting, machine


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--spheres", type=int, action="append")
    parser.add_argument("--size", default="1680x1050")
    parser.add_argument("--depth", type=int, default=5)
    parser.add_argument("--shadow-samples", type=int, default=4)
    parser.add_argument("--frames", type=int, default=7)
    parser.add_argument("--wave-grid", type=int, action="append", help="blocks a stage (0: the default)")
    args = parser.parse_args()
    width, height = (int(v) for v in args.size.split("x"))
    for n in args.spheres or [1000, 10_000, 100_000]:
        scene = raybench.random_spheres(n, seed=0, materials=True)
        shading = lighting.Shading.of(scene, args.depth, args.shadow_samples)
        basis = Camera().basis(width, height)
        grids = args.wave_grid or [0]
        tracers = {
            g: backends.tracer("cuda", scene.spheres, width, height, whitted=shading, wave_grid=g or None)
            for g in grids
        }
        for tracer in tracers.values():
            tracer.trace(basis)  # compiled, queues grown
        kernel = {g: [] for g in grids}
        stages = {}
        for _ in range(args.frames):
            for g, tracer in tracers.items():
                kernel[g].append(tracer.timed_trace(basis))
        tracer = tracers[grids[0]]
        for _ in range(args.frames):
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
        print(
            json.dumps(
                {
                    "spheres": n,
                    "size": args.size,
                    "rays": dict(zip(("primary", "shadow", "reflection", "refraction"), tracer.ray_counts.tolist())),
                    "kernel_ms_by_grid": {str(g): statistics.median(v) for g, v in kernel.items()},
                    "stage_ms": {s: statistics.median(v) for s, v in stages.items()},
                    "git_commit": machine.git_commit(),
                }
            ),
            flush=True,
        )
        for tracer in tracers.values():
            tracer.close()
    return 0


if __name__ == "__main__":
    sys.exit(main())
