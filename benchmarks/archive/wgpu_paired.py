"""The wgpu backend against the CPU on one shared machine: frames interleaved (cpu, wgpu, cpu,
wgpu, ...) so that both see the same load from other users, and their ratio per round. Both run
the simple kernel (the thesis's loop). One record of the results schema (suite "scaling", accel
"none", kernel "simple") per device and workgroup; each wgpu record carries whether its picture
is the CPU's and the median of its rounds' kernel time over the CPU's frame.

    PYTHONPATH=benchmarks python benchmarks/archive/wgpu_paired.py --adapter llvmpipe --spheres 300 --size 640x480 \\
        --rounds 5 --out out.jsonl
"""

import argparse
import sys
import time

import _harness
import numpy as np

from raybench import Camera, backends, random_spheres
from raybench.cli import parse_pair, parse_size


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--adapter")
    ap.add_argument("--spheres", type=int, default=300)
    ap.add_argument("--size", default="640x480")
    ap.add_argument("--workgroup", action="append", default=None, help="XxY; repeat for several")
    _harness.add_common(ap, frames=1, rounds=5)
    args = ap.parse_args()
    _harness.check_common(ap, args)
    width, height = parse_size(args.size)
    scene = random_spheres(args.spheres, 0)
    basis = Camera().basis(width, height)
    shapes = [parse_pair(w, "--workgroup", "16x16") for w in (args.workgroup or ["16x16"])]
    cpu = backends.tracer("cpu", scene.spheres, width, height, kernel="simple")
    gpus = {
        (x, y): backends.tracer("wgpu", scene.spheres, width, height, adapter=args.adapter, workgroup=(x, y))
        for x, y in shapes
    }
    try:
        cpu.compile()
        cpu_image, cpu_hits = (a.copy() for a in cpu.trace(basis))
        same = {}
        for shape, t in gpus.items():
            t.compile()
            image, hits = t.trace(basis)
            same[shape] = {
                "hits_equal": bool(np.array_equal(hits, cpu_hits)),
                "max_colour_step": int(np.abs(image.astype(int) - cpu_image.astype(int)).max()),
            }
        kernels = {shape: [] for shape in gpus}

        def wgpu_frame(shape):
            start = time.perf_counter()
            kernels[shape].append(gpus[shape].timed_trace(basis))
            return (time.perf_counter() - start) * 1e3

        variants = {"cpu": lambda: _harness.timings(lambda: cpu.trace(basis), args.frames)}
        variants.update({shape: (lambda s=shape: [wgpu_frame(s) for _ in range(args.frames)]) for shape in gpus})
        times = _harness.paired(variants, args.rounds)
        settings = {"adapter": args.adapter, "spheres": args.spheres}
        with _harness.Records("wgpu_paired", args, settings) as out:
            brute = {"accel": "none", "kernel": "simple"}
            record = _harness.point(
                "scaling", "cpu", width, height, args.spheres, {**brute, "threads": cpu.threads}, times["cpu"]
            )
            record["tests_per_s"] = record["rays_per_s"] * args.spheres
            out.write(record)
            for shape, t in gpus.items():
                record = _harness.point(
                    "scaling", "wgpu", width, height, args.spheres, {**brute, "block": list(shape)}, times[shape],
                    kernels[shape] if all(k is not None for k in kernels[shape]) else None,
                )  # fmt: skip
                record["tests_per_s"] = record["rays_per_s"] * args.spheres
                record["adapter"] = {k: v for k, v in t.describe().items() if isinstance(v, (str, int, float))}
                record["same_picture"] = same[shape]
                if record["kernel_ms"]:
                    ratios = [k / c for k, c in zip(kernels[shape], times["cpu"])]
                    record["wgpu_over_cpu_time"] = _harness.median(ratios)
                out.write(record)
    finally:
        cpu.close()
        for t in gpus.values():
            t.close()
    return 0


if __name__ == "__main__":
    sys.exit(main())
