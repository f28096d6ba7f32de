"""The CPU's Whitted frame with every ray alone through the binary tree (tree_width 2) against
the packets program (tree_width 4, the default; issue 27 item 2: each tile's primary rays and
each hit's shadow rays as packets through the 4-wide tree, the reflected and refracted rays
through it a ray at a time), side by side in one process: two Tracers of the same scene, their
frames taken in turn, so that both meet the same load on a shared machine. The issue's scene
(random_spheres(n, seed=0, materials=True)), depth 5, 4 shadow samples.

Each frame is timed by the wall clock and by the process's CPU time (time.process_time, all
its threads): where other work shares the cores, the CPU time is the fairer clock. rays/s
counts every ray of the frame; per CPU second it is the rays over the CPU seconds spent.
The two frames are checked to be the same, bit for bit, with the same rays. One record of the
results schema's "parts" suite a side: its frames' CPU times, the wall time, rays and the check
in its values.

    PYTHONPATH=src:benchmarks python benchmarks/archive/cpu_shadow_packets.py --spheres 1000 10000 --threads 1 2
"""

import argparse
import sys
import time

import _harness
import numpy as np

import raybench
from raybench import Camera, backends, lighting

SIDES = {"per_ray": 2, "packets": 4}


def timed(tracer, basis):
    wall, process = time.perf_counter(), time.process_time()
    tracer.trace(basis)
    return (time.perf_counter() - wall) * 1e3, (time.process_time() - process) * 1e3


def one(records, spheres, width, height, threads, frames, depth, samples):
    scene = raybench.random_spheres(spheres, seed=0, materials=True)
    shading = lighting.Shading.of(scene, depth, samples)
    basis = Camera().basis(width, height)
    tracers = {
        side: backends.tracer("cpu", scene.spheres, width, height, threads=threads, whitted=shading, tree_width=w)
        for side, w in SIDES.items()
    }
    try:
        for tracer in tracers.values():
            tracer.trace(basis)  # compiled
        a, b = tracers["per_ray"], tracers["packets"]
        same = np.array_equal(a.image, b.image) and np.array_equal(a.hits, b.hits)
        same = same and np.array_equal(a.ray_counts, b.ray_counts)
        times = {side: [] for side in tracers}
        for _ in range(frames):
            for side, tracer in tracers.items():
                times[side].append(timed(tracer, basis))
        rays = int(a.ray_counts.sum())
        for side, pairs in times.items():
            wall = [w for w, _ in pairs]
            process = [p for _, p in pairs]
            values = {
                "wall_ms": _harness.median(wall),
                "rays": rays,
                "rays_per_cpu_s": rays / (_harness.median(process) / 1e3),
                "same_frame": 1 if same else 0,
            }
            options = {"shadows": side, "threads": threads, "depth": depth, "shadow_samples": samples}
            records.write(
                _harness.part(
                    "whitted-frame-cpu-time", "cpu", process, spheres=spheres, width=width, height=height,
                    options=options, values=values,
                )
            )  # fmt: skip
    finally:
        for tracer in tracers.values():
            tracer.close()


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--spheres", type=int, nargs="+", default=[1000, 10000])
    parser.add_argument("--threads", type=int, nargs="+", default=[1, 2])
    parser.add_argument("--size", type=int, nargs=2, default=[420, 262])
    parser.add_argument("--depth", type=int, default=5)
    parser.add_argument("--samples", type=int, default=4)
    _harness.add_common(parser, frames=7)
    args = parser.parse_args()
    _harness.check_common(parser, args)
    settings = {"size": args.size, "depth": args.depth, "shadow_samples": args.samples, "frames": args.frames}
    with _harness.Records("cpu_shadow_packets", args, settings) as records:
        for _ in range(args.rounds):
            for spheres in args.spheres:
                for threads in args.threads:
                    one(records, spheres, *args.size, threads, args.frames, args.depth, args.samples)
    return 0


if __name__ == "__main__":
    sys.exit(main())
