"""What raybench.Renderer costs over the backend's own Tracer, warm, side by
side: the Tracer's trace() (its buffers reused), Renderer.render() (a Frame
of its own arrays, dropped at once, so its arrays are traced into again),
Renderer.render(hits=False), and Renderer.render() by a caller who keeps the
last KEPT frames (past the Renderer's lent arrays, copies), taken in turn
frame by frame, medians. Where the device times its kernel (cuda), also the
kernel alone and the frame's bytes at the host link's speed, measured here
by a copy of as many bytes from the device into pinned memory, so that the
whole frame can be held to the kernel plus its copy. One line of JSON a size.

    python benchmarks/renderer_overhead.py --device cpu --spheres 1000 --frames 31
    python benchmarks/renderer_overhead.py --device cuda --spheres 1000 --spheres 100000
"""

import argparse
import collections
import json
import statistics
import sys
import time

import numpy as np

import raybench
from raybench import machine

KEPT = 10


def timed(call) -> float:
    start = time.perf_counter()
    call()
    return (time.perf_counter() - start) * 1e3


def copy_ms(nbytes: int, repeats: int = 11) -> float:
    """A copy of nbytes from the GPU into page-locked host memory, median ms."""
    from numba import cuda

    device = cuda.device_array(nbytes, np.uint8)
    host = cuda.pinned_array(nbytes, np.uint8)
    times = []
    for _ in range(repeats):
        cuda.synchronize()
        start = time.perf_counter()
        device.copy_to_host(host)
        cuda.synchronize()
        times.append((time.perf_counter() - start) * 1e3)
    return statistics.median(times)


def measure(n: int, width: int, height: int, device: str, frames: int) -> dict:
    scene = raybench.random_spheres(n, seed=0)
    camera = raybench.Camera()
    basis = camera.basis(width, height)
    kept = collections.deque(maxlen=KEPT)
    # the kept frames from a renderer of their own: from the one timed with
    # frames dropped, they would take the arrays that its next frame would
    # trace into again, and leave it fresh memory each frame
    with (
        raybench.Renderer(scene, width, height, device=device) as renderer,
        raybench.Renderer(scene, width, height, device=device) as keeper,
    ):
        tracer = renderer.tracer
        ways = {
            "tracer_trace": lambda: tracer.trace(basis),
            "renderer_render": lambda: renderer.render(camera),
            "renderer_render_no_hits": lambda: renderer.render(camera, hits=False),
            "renderer_render_kept": lambda: kept.append(keeper.render(camera)),
        }
        for call in ways.values():  # warm: compiled, built, buffers made
            call()
        times = {name: [] for name in ways}
        kernel = []
        for _ in range(frames):
            for name, call in ways.items():
                times[name].append(timed(call))
            if device == "cuda":
                kernel.append(tracer.timed_trace(basis))
        kept.clear()
        row = {"device": tracer.name, "spheres": n, "width": width, "height": height, "frames": frames, "kept": KEPT}
        row.update({f"{name}_ms": round(statistics.median(t), 3) for name, t in times.items()})
        base = row["tracer_trace_ms"]
        row["render_over_trace"] = round(row["renderer_render_ms"] / base, 3)
        row["render_no_hits_over_trace"] = round(row["renderer_render_no_hits_ms"] / base, 3)
        row["render_kept_over_trace"] = round(row["renderer_render_kept_ms"] / base, 3)
        if device == "cuda":
            frame_bytes = width * height * (3 + 4)  # the image's RGB bytes and the int32 hits
            row["kernel_ms"] = round(statistics.median(kernel), 3)
            row["copy_ms"] = round(copy_ms(frame_bytes), 3)
            floor = row["kernel_ms"] + row["copy_ms"]
            row["render_over_kernel_plus_copy"] = round(row["renderer_render_ms"] / floor, 3)
        return row


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--device", default="cpu", choices=("cpu", "cuda", "wgpu"))
    parser.add_argument("--spheres", type=int, action="append", help="default: 1000")
    parser.add_argument("--size", default="1680x1050")
    parser.add_argument("--frames", type=int, default=31)
    args = parser.parse_args()
    width, height = (int(v) for v in args.size.split("x"))
    print(json.dumps({"what": "run", "git_commit": machine.git_commit(), "machine": machine.describe()["cpu"]}))
    for n in args.spheres or [1000]:
        print(json.dumps(measure(n, width, height, args.device, args.frames)), flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
