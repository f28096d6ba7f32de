"""The BVH walk at the issue's sizes: one record of the results schema (suite "scaling",
accel "bvh") per (device, size), with the frames' and, on cuda and wgpu, the kernel's own times
(CUDA events, wgpu GPU timestamps), the walk that ran and the build's time. `raybench report`
reads them.

For A/B runs of two versions in one lease, side by side: run it once per version's source tree,
alternating, each with its own --label, e.g.

    PYTHONPATH=old/src python benchmarks/bvh_walks.py --device cuda --label old --out walks.jsonl
    PYTHONPATH=src     python benchmarks/bvh_walks.py --device cuda --label new --out walks.jsonl
"""

import argparse
import sys
import time

import _harness

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
        start = time.perf_counter()
        tracer.trace(basis)  # warm: compiled, uploaded
        first_s = time.perf_counter() - start
        whole, kernel = [], []
        for _ in range(frames):
            start = time.perf_counter()
            kernel_ms = tracer.timed_trace(basis)
            whole.append((time.perf_counter() - start) * 1e3)
            if kernel_ms is not None:
                kernel.append(kernel_ms)
        shape = getattr(tracer, "block", None) or getattr(tracer, "workgroup", None)  # cuda's, wgpu's
        used = {"accel": "bvh"}
        if shape is not None:
            used["block"] = list(shape)
        if getattr(tracer, "threads", None) is not None:
            used["threads"] = tracer.threads
        record = _harness.point(
            "scaling", device, width, height, spheres, used, whole, kernel or None,
            first_frame_s=first_s, compile_s=None, build_s=tracer.build_s,
        )  # fmt: skip
        # rays a second from the kernel's own time where the device gives it, as the report does
        record["rays_per_s"] = width * height / ((record["kernel_ms"] or record["frame_ms"])["median"] / 1e3)
        record["walk"] = getattr(tracer, "walk", None)
        record["raybench"] = raybench.__file__  # which source tree ran (A/B runs)
        return record
    finally:
        tracer.close()


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--device", action="append", choices=["cpu", "cuda", "wgpu"])
    parser.add_argument("--size", action="append", choices=sorted(SIZES))
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
    _harness.add_common(parser, frames=9)
    args = parser.parse_args()
    _harness.check_common(parser, args)
    if args.threads is not None and args.threads < 1:
        parser.error(f"--threads: must be at least 1, got {args.threads}")
    settings = {"block": args.block, "walk": args.walk, "threads": args.threads, "frames": args.frames}
    try:
        with _harness.Records("bvh_walks", args, settings) as out:
            for _ in range(args.rounds):
                for device in args.device or ["cuda"]:
                    for size in args.size or list(ISSUE_SIZES):
                        out.write(one(device, *SIZES[size], args.frames, args.block, args.walk, args.threads))
    except RaybenchError as error:
        print(f"bvh_walks: {error}", file=sys.stderr)
        return 2
    return 0


if __name__ == "__main__":
    sys.exit(main())
