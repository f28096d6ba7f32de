"""The kernels against the hardware: measured FP32 peak of each processor,
the simple and fast kernels side by side on the same frame (their images must
be identical on the CPU; on a GPU the compiler may fuse multiply-adds
differently in the two kernels), and a sweep of the CUDA fast kernel's shape. Writes JSON.

    python benchmarks/kernels.py --json kernels.json [--frames 7] [--sweep | --sweep-trip]

The figures in docs/floors.md come from this script.
"""

import argparse
import json
import statistics
import sys
import time

import numpy as np

import raybench
from raybench import backends, files, machine
from raybench.bench import peak


def frames(tracer, basis, n):
    """Median whole-frame ms and median kernel ms (None on the CPU) over n warm frames."""
    tracer.trace(basis)
    walls, kernels = [], []
    for _ in range(n):
        t = time.perf_counter()
        k = tracer.timed_trace(basis)
        walls.append((time.perf_counter() - t) * 1e3)
        if k is not None:
            kernels.append(k)
    return statistics.median(walls), (statistics.median(kernels) if kernels else None)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--json", required=True)
    ap.add_argument("--frames", type=int, default=7)
    ap.add_argument("--size", default="1680x1050")
    ap.add_argument("--spheres", type=int, default=1000)
    ap.add_argument("--sweep", action="store_true", help="the CUDA fast kernel's rays, tile and block shapes")
    ap.add_argument("--sweep-trip", action="store_true", help="its spheres per trip of the cull loop")
    ap.add_argument("--skip-peak", action="store_true")
    args = ap.parse_args()
    w, h = map(int, args.size.split("x"))
    out = {
        "git_commit": machine.git_commit(),
        "machine": machine.describe(),
        "size": [w, h],
        "spheres": args.spheres,
        "peak": {},
        "kernels": [],
        "sweep": [],
    }
    # wgpu has the simple kernel alone: nothing to set side by side here
    devices = [d for d in backends.present() if d != "wgpu"]
    if not args.skip_peak:
        out["peak"]["cpu"] = peak.cpu_peak()
        print("peak", out["peak"]["cpu"], flush=True)
        if "cuda" in devices:
            out["peak"]["cuda"] = peak.cuda_peak()
            print("peak", out["peak"]["cuda"], flush=True)
    scene = raybench.random_spheres(args.spheres, seed=0)
    basis = raybench.Camera().basis(w, h)
    tests = w * h * args.spheres
    for device in devices:
        images = {}
        for kernel in ("simple", "fast"):
            tracer = backends.tracer(device, scene.spheres, w, h, kernel=kernel)
            compile_s = tracer.compile()
            wall, kern = frames(tracer, basis, args.frames)
            images[kernel] = (tracer.image.copy(), tracer.hits.copy())
            best = kern if kern is not None else wall
            rec = {
                "device": device,
                "kernel": kernel,
                "frame_ms": wall,
                "kernel_ms": kern,
                "tests_per_s": tests / (best / 1e3),
                "compile_s": compile_s,
            }
            out["kernels"].append(rec)
            print(json.dumps(rec), flush=True)
            tracer.close()
        (img_s, hits_s), (img_f, hits_f) = images["simple"], images["fast"]
        diff = np.abs(img_s.astype(int) - img_f.astype(int))
        same = {
            "images_identical": bool(np.array_equal(img_s, img_f)),
            "hits_differing": int((hits_s != hits_f).sum()),
            "pixels_differing": int(diff.max(axis=2).astype(bool).sum()),
            "max_colour_step": int(diff.max()),
        }
        out.setdefault("identical", {})[device] = same
        print(device, "simple against fast:", same, flush=True)
    if (args.sweep or args.sweep_trip) and "cuda" in devices:
        if args.sweep:
            shapes = [
                (rays, tile, 2, block)
                for rays in (1, 2, 4, 8, 16)
                for tile in (128, 256, 512)
                for block in ((32, 2), (16, 4), (32, 4), (32, 8), (16, 16), (64, 4), (128, 1))
            ]
        else:  # spheres per trip of the cull loop, around the default shape, twice over
            shapes = [
                (8, 256, trip, block) for _ in range(2) for trip in (1, 2, 3, 4) for block in ((16, 4), (32, 2), (8, 8))
            ]
        for rays, tile, trip, block in shapes:
            tracer = backends.tracer("cuda", scene.spheres, w, h, rays=rays, tile=tile, trip=trip, block=block)
            tracer.compile()
            wall, kern = frames(tracer, basis, args.frames)
            rec = {
                "rays": rays,
                "tile": tile,
                "trip": trip,
                "block": list(block),
                "frame_ms": wall,
                "kernel_ms": kern,
                "tests_per_s": tests / (kern / 1e3),
            }
            out["sweep"].append(rec)
            print(json.dumps(rec), flush=True)
    files.write_atomic(args.json, json.dumps(out, indent=1).encode())


if __name__ == "__main__":
    sys.exit(main())
