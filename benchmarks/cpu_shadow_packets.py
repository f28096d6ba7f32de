"""The CPU's Whitted frame with each hit's shadow rays ray by ray (tree_width 2, the binary
tree) against as packets through the 4-wide tree (tree_width 4, the default; issue 27 item
2), side by side in one process: two Tracers of the same scene, their frames taken in turn,
so that both meet the same load on a shared machine. The issue's scene
(random_spheres(n, seed=0, materials=True)), depth 5, 4 shadow samples.

Each frame is timed by the wall clock and by the process's CPU time (time.process_time, all
its threads): where other work shares the cores, the CPU time is the fairer clock. rays/s
counts every ray of the frame; per CPU second it is the rays over the CPU seconds spent.
The two frames are checked to be the same, bit for bit, with the same rays.

    PYTHONPATH=src python benchmarks/cpu_shadow_packets.py --spheres 1000 10000 --threads 1 2
"""

import argparse
import json
import os
import platform
import statistics
import time

import numpy as np

import raybench
from raybench import Camera, lighting
from raybench.backends import cpu

SIDES = {"per_ray": 2, "packets": 4}


def timed(tracer, basis):
    wall, process = time.perf_counter(), time.process_time()
    tracer.trace(basis)
    return time.perf_counter() - wall, time.process_time() - process


def one(spheres, width, height, threads, frames, depth, samples):
    scene = raybench.random_spheres(spheres, seed=0, materials=True)
    shading = lighting.Shading.of(scene, depth, samples)
    basis = Camera().basis(width, height)
    tracers = {
        side: cpu.Tracer(scene.spheres, width, height, threads=threads, whitted=shading, tree_width=w)
        for side, w in SIDES.items()
    }
    try:
        for tracer in tracers.values():
            tracer.trace(basis)  # compiled
        a, b = tracers["per_ray"], tracers["packets"]
        same = bool(np.array_equal(a.image, b.image) and np.array_equal(a.hits, b.hits))
        same &= bool(np.array_equal(a.ray_counts, b.ray_counts))
        times = {side: [] for side in tracers}
        for _ in range(frames):
            for side, tracer in tracers.items():
                times[side].append(timed(tracer, basis))
        rays = int(a.ray_counts.sum())
        record = {
            "spheres": spheres,
            "size": [width, height],
            "threads": threads,
            "depth": depth,
            "shadow_samples": samples,
            "rays": dict(zip(("primary", "shadow", "reflection", "refraction"), a.ray_counts.tolist())),
            "same_frame": same,
        }
        for side, pairs in times.items():
            wall = statistics.median(p[0] for p in pairs)
            process = statistics.median(p[1] for p in pairs)
            record[side] = {
                "wall_ms": wall * 1e3,
                "cpu_ms": process * 1e3,
                "rays_per_s": rays / wall,
                "rays_per_cpu_s": rays / process,
            }
        record["speedup_cpu_time"] = record["per_ray"]["cpu_ms"] / record["packets"]["cpu_ms"]
        record["speedup_wall"] = record["per_ray"]["wall_ms"] / record["packets"]["wall_ms"]
        return record
    finally:
        for tracer in tracers.values():
            tracer.close()


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--spheres", type=int, nargs="+", default=[1000, 10000])
    parser.add_argument("--threads", type=int, nargs="+", default=[1, 2])
    parser.add_argument("--size", type=int, nargs=2, default=[420, 262])
    parser.add_argument("--frames", type=int, default=7)
    parser.add_argument("--depth", type=int, default=5)
    parser.add_argument("--samples", type=int, default=4)
    parser.add_argument("--out", help="append each record to this JSON-lines file")
    args = parser.parse_args()
    for spheres in args.spheres:
        for threads in args.threads:
            record = one(spheres, *args.size, threads, args.frames, args.depth, args.samples)
            record.update(
                what="cpu_shadow_packets",
                machine=platform.processor() or platform.machine(),
                cpus=os.cpu_count(),
                load_avg=os.getloadavg(),  # 1, 5, 15 minutes, after the record
            )
            line = json.dumps(record)
            print(line, flush=True)
            if args.out:
                with open(args.out, "a") as out:
                    out.write(line + "\n")


if __name__ == "__main__":
    main()
