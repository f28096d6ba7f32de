"""Whitted shading's throughput, one line of JSON per (device, spheres, accel):
the issue's scene (random_spheres(n, materials=True): mixed materials, one
area light), depth 5, 4 shadow samples, 1680x1050 by default. Median kernel
time (CUDA events, wgpu GPU timestamps; on the CPU the frame's wall time),
median whole frame, the rays the kernel counted by kind, and rays a second
with every kind counted, over the kernel time and over the whole frame.

For A/B runs of two versions, as bvh_walks.py: PYTHONPATH=old/src, then src.
"""

import argparse
import json
import statistics
import sys
import time

import raybench
from raybench import Camera, RaybenchError, backends, lighting


def one(device, spheres, width, height, frames, accel, depth, samples, block=None) -> dict:
    scene = raybench.random_spheres(spheres, seed=0, materials=True)
    shading = lighting.Shading.of(scene, depth, samples)
    basis = Camera().basis(width, height)
    options = {"cuda": {"block": block}, "wgpu": {"workgroup": block}}.get(device, {}) if block else {}
    with backends.tracer(device, scene.spheres, width, height, accel=accel, whitted=shading, **options) as tracer:
        start = time.perf_counter()
        tracer.trace(basis)  # compiled, uploaded
        first_s = time.perf_counter() - start
        kernel, whole = [], []
        for _ in range(frames):
            start = time.perf_counter()
            kernel_ms = tracer.timed_trace(basis)
            whole.append((time.perf_counter() - start) * 1e3)
            kernel.append(kernel_ms if kernel_ms is not None else whole[-1])
        rays = dict(zip(("primary", "shadow", "reflection", "refraction"), tracer.ray_counts.tolist()))
        total = sum(rays.values())
        kernel_ms, frame_ms = statistics.median(kernel), statistics.median(whole)
        return {
            "device": device,
            "accel": accel,
            "block": getattr(tracer, "block", None) or getattr(tracer, "workgroup", None),
            **_resources(tracer),
            "spheres": spheres,
            "width": width,
            "height": height,
            "depth": depth,
            "shadow_samples": samples,
            "frames": frames,
            "kernel_ms": round(kernel_ms, 4),
            "frame_ms": round(frame_ms, 4),
            "first_frame_s": round(first_s, 2),
            "rays": rays,
            "grays_per_s_kernel": round(total / kernel_ms / 1e6, 4),
            "grays_per_s_frame": round(total / frame_ms / 1e6, 4),
            "kernel_time": tracer.timed_trace(basis) is not None,
            "threads": getattr(tracer, "threads", None),
            "raybench": raybench.__file__,
        }


def _resources(tracer) -> dict:
    """cuda: the Whitted kernel's registers and local memory a thread (spills
    and the stacks); other devices: nothing."""
    if tracer.name != "cuda":
        return {}
    kernel = tracer._kernel
    try:
        (signature,) = kernel.overloads.keys()
        return {
            "regs": kernel.get_regs_per_thread(signature),
            "local_bytes": kernel.get_local_mem_per_thread(signature),
        }
    except Exception as exc:  # noqa: BLE001 - a numba-cuda without the query: the record says so
        return {"resources": f"unknown ({exc.__class__.__name__})"}


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--device", action="append", choices=["cpu", "cuda", "wgpu"])
    parser.add_argument("--spheres", action="append", type=int)
    parser.add_argument("--accel", action="append", choices=["bvh", "none"])
    parser.add_argument("--size", default="1680x1050")
    parser.add_argument("--frames", type=int, default=7)
    parser.add_argument("--depth", type=int, default=5)
    parser.add_argument("--shadow-samples", type=int, default=4)
    parser.add_argument("--block", type=int, nargs=2, metavar=("X", "Y"), help="cuda's block, wgpu's workgroup")
    args = parser.parse_args()
    width, height = (int(v) for v in args.size.split("x"))
    for device in args.device or ["cuda"]:
        for accel in args.accel or ["bvh"]:
            for n in args.spheres or [1000, 10_000, 100_000]:
                try:
                    row = one(device, n, width, height, args.frames, accel, args.depth, args.shadow_samples, args.block)
                except RaybenchError as exc:
                    row = {"device": device, "accel": accel, "spheres": n, "error": str(exc)}
                print(json.dumps(row), flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
