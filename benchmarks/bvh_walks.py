"""The BVH walk at the issue's sizes, one line of JSON per (device, size): the
median kernel time (CUDA events, wgpu GPU timestamps; on the CPU the whole
frame's wall time), rays a second, the build's time, and which raybench ran.

For A/B runs of two versions in one lease, side by side: run it once per
version's source tree, alternating, e.g.

    PYTHONPATH=old/src python benchmarks/bvh_walks.py --device cuda
    PYTHONPATH=src     python benchmarks/bvh_walks.py --device cuda
"""

import argparse
import json
import statistics
import sys
import time

import raybench
from raybench import Camera, RaybenchError, backends

# The issue's three sizes (the default), and between them for where curves cross
ISSUE_SIZES = {"1k": (1000, 1680, 1050), "100k": (100_000, 1680, 1050), "1M": (1_000_000, 1920, 1080)}
SIZES = {
    **ISSUE_SIZES,
    "3k": (3000, 1680, 1050),
    "10k": (10_000, 1680, 1050),
    "30k": (30_000, 1680, 1050),
    "300k": (300_000, 1680, 1050),
}


def one(device: str, spheres: int, width: int, height: int, frames: int, block, walk, threads) -> dict:
    scene = raybench.random_spheres(spheres, seed=0)
    basis = (scene.camera or Camera()).basis(width, height)
    options = {"cuda": {"block": block, "walk": walk}, "wgpu": {"workgroup": block, "walk": walk}}.get(device, {})
    options = {key: value for key, value in options.items() if value}
    if device == "cpu" and threads:
        options["threads"] = threads
    tracer = backends.tracer(device, scene.spheres, width, height, accel="bvh", **options)
    try:
        tracer.trace(basis)  # warm: compiled, uploaded
        times = []
        for _ in range(frames):
            start = time.perf_counter()
            kernel_ms = tracer.timed_trace(basis)
            times.append(kernel_ms if kernel_ms is not None else (time.perf_counter() - start) * 1e3)
        ms = statistics.median(times)
        shape = getattr(tracer, "block", None) or getattr(tracer, "workgroup", None)  # cuda's, wgpu's
        return {
            "device": device,
            "walk": getattr(tracer, "walk", None),
            "block": shape,
            "spheres": spheres,
            "width": width,
            "height": height,
            "frames": frames,
            "median_ms": round(ms, 4),
            "grays_per_s": round(width * height / ms / 1e6, 3),
            "build_ms": round(tracer.build_s * 1e3, 1),
            "kernel_time": kernel_ms is not None,
            "threads": getattr(tracer, "threads", None),
            "raybench": raybench.__file__,
        }
    finally:
        tracer.close()


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--device", action="append", choices=["cpu", "cuda", "wgpu"])
    parser.add_argument("--size", action="append", choices=sorted(SIZES))
    parser.add_argument("--frames", type=int, default=9)
    parser.add_argument(
        "--block",
        type=int,
        nargs=2,
        metavar=("X", "Y"),
        help="cuda's block shape, wgpu's workgroup (default: the walk's own)",
    )
    parser.add_argument(
        "--walk",
        help="cuda's and wgpu's BVH walk, ray or packet (default: on cuda chosen by the tree's size, on wgpu ray)",
    )
    parser.add_argument("--threads", type=int, help="cpu's threads (default: every core)")
    args = parser.parse_args()
    if args.frames < 1:
        parser.error(f"--frames: must be at least 1, got {args.frames}")
    if args.threads is not None and args.threads < 1:
        parser.error(f"--threads: must be at least 1, got {args.threads}")
    try:
        for device in args.device or ["cuda"]:
            for size in args.size or list(ISSUE_SIZES):
                print(
                    json.dumps(one(device, *SIZES[size], args.frames, args.block, args.walk, args.threads)), flush=True
                )
    except RaybenchError as error:
        print(f"bvh_walks: {error}", file=sys.stderr)
        return 2
    return 0


if __name__ == "__main__":
    sys.exit(main())
