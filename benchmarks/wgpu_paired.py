"""The wgpu backend against the CPU on one shared machine: frames interleaved
(cpu, wgpu, cpu, wgpu, ...) so that both see the same load from other users,
and their ratio per round. Both run the simple kernel (the thesis's loop).

    python benchmarks/wgpu_paired.py --adapter llvmpipe --spheres 300 --size 640x480 --rounds 5 --json out.json
"""

import argparse
import json
import os
import statistics
import time

import numpy as np

from raybench import Camera, backends, files, random_spheres
from raybench.cli import parse_pair, parse_size
from raybench.machine import describe, git_commit


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--adapter")
    ap.add_argument("--spheres", type=int, default=300)
    ap.add_argument("--size", default="640x480")
    ap.add_argument("--rounds", type=int, default=5)
    ap.add_argument("--workgroup", action="append", default=None, help="XxY; repeat for several")
    ap.add_argument("--json")
    args = ap.parse_args()
    width, height = parse_size(args.size)
    scene = random_spheres(args.spheres, 0)
    basis = Camera().basis(width, height)
    shapes = [parse_pair(w, "--workgroup", "16x16") for w in (args.workgroup or ["16x16"])]
    cpu = backends.tracer("cpu", scene.spheres, width, height, kernel="simple")
    gpus = {
        f"{x}x{y}": backends.tracer("wgpu", scene.spheres, width, height, adapter=args.adapter, workgroup=(x, y))
        for x, y in shapes
    }
    cpu.compile()
    cpu_image, cpu_hits = (a.copy() for a in cpu.trace(basis))
    same = {}
    for name, t in gpus.items():
        t.compile()
        image, hits = t.trace(basis)
        same[name] = {
            "hits_equal": bool(np.array_equal(hits, cpu_hits)),
            "max_colour_step": int(np.abs(image.astype(int) - cpu_image.astype(int)).max()),
        }
    rounds = []
    for _ in range(args.rounds):
        row = {"load1": os.getloadavg()[0]}
        start = time.perf_counter()
        cpu.trace(basis)
        row["cpu_ms"] = (time.perf_counter() - start) * 1e3
        for name, t in gpus.items():
            start = time.perf_counter()
            row[f"wgpu_{name}_kernel_ms"] = t.timed_trace(basis)
            row[f"wgpu_{name}_frame_ms"] = (time.perf_counter() - start) * 1e3
        rounds.append(row)
        print(json.dumps({k: round(v, 2) for k, v in row.items()}), flush=True)
    tests = width * height * args.spheres
    summary = {"cpu_ms": statistics.median(r["cpu_ms"] for r in rounds)}
    for name in gpus:
        k = statistics.median(r[f"wgpu_{name}_kernel_ms"] for r in rounds)
        ratio = statistics.median(r[f"wgpu_{name}_kernel_ms"] / r["cpu_ms"] for r in rounds)
        summary[name] = {"kernel_ms": k, "tests_per_s": tests / (k / 1e3), "wgpu_over_cpu_time": ratio}
    summary["cpu_tests_per_s"] = tests / (summary["cpu_ms"] / 1e3)
    adapter = next(iter(gpus.values())).describe()
    print(json.dumps({"adapter": adapter, "same_picture": same, "summary": summary}, indent=1))
    if args.json:
        record = {
            "argv": vars(args),
            "git_commit": git_commit(),
            "machine": describe(),
            "adapter": adapter,
            "same_picture": same,
            "rounds": rounds,
            "summary": summary,
        }
        files.write_atomic(args.json, json.dumps(record, indent=1).encode())


if __name__ == "__main__":
    main()
