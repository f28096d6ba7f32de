"""What raybench.Renderer costs over the backend's own Tracer, warm, side by side: the Tracer's
trace() (its buffers reused), Renderer.render() (a Frame of its own arrays, dropped at once, so
its arrays are traced into again), Renderer.render(hits=False), and Renderer.render() by a
caller who keeps the last KEPT frames (past the Renderer's lent arrays, copies), taken in turn
frame by frame. Where the device times its kernel (cuda), also the kernel alone and the frame's
bytes at the host link's speed, measured here by a copy of as many bytes from the device into
pinned memory, so that the whole frame can be held to the kernel plus its copy. Records of the
results schema's "parts" suite, a way and size each (quantity "tracer-trace", "renderer-render",
..., "kernel", "copy-to-host"), each with its ratio to the Tracer's trace.

    PYTHONPATH=benchmarks python benchmarks/archive/renderer_overhead.py --device cpu --spheres 1000 --frames 31
    PYTHONPATH=benchmarks python benchmarks/archive/renderer_overhead.py --device cuda --spheres 1000 --spheres 100000
"""

import argparse
import collections
import sys

import _harness
import numpy as np

import raybench

KEPT = 10


def copy_ms(nbytes: int, repeats: int = 11) -> list[float]:
    """Copies of nbytes from the GPU into page-locked host memory, ms each."""
    from numba import cuda

    device = cuda.device_array(nbytes, np.uint8)
    host = cuda.pinned_array(nbytes, np.uint8)

    def copy():
        cuda.synchronize()
        device.copy_to_host(host)
        cuda.synchronize()

    return _harness.timings(copy, repeats)


def measure(out, n: int, width: int, height: int, device: str, frames: int) -> None:
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
            "tracer-trace": lambda: tracer.trace(basis),
            "renderer-render": lambda: renderer.render(camera),
            "renderer-render-no-hits": lambda: renderer.render(camera, hits=False),
            "renderer-render-kept": lambda: kept.append(keeper.render(camera)),
        }
        for call in ways.values():  # warm: compiled, built, buffers made
            call()
        times = _harness.paired({name: _harness.timed(call) for name, call in ways.items()}, frames)
        if device == "cuda":
            times["kernel"] = [tracer.timed_trace(basis) for _ in range(frames)]
            times["copy-to-host"] = copy_ms(width * height * (3 + 4))  # the image's RGB bytes and the int32 hits
        kept.clear()
        base = _harness.median(times["tracer-trace"])
        for name, samples in times.items():
            values = {"over_trace": round(_harness.median(samples) / base, 3)}
            if name == "renderer-render-kept":
                values["kept"] = KEPT
            if name == "copy-to-host":
                values = {"bytes": width * height * 7}
            out.write(_harness.part(name, tracer.name, samples, spheres=n, width=width, height=height, values=values))


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--device", default="cpu", choices=("cpu", "cuda", "wgpu"))
    parser.add_argument("--spheres", type=int, action="append", help="default: 1000")
    parser.add_argument("--size", default="1680x1050")
    _harness.add_common(parser, frames=31)
    args = parser.parse_args()
    _harness.check_common(parser, args)
    width, height = (int(v) for v in args.size.split("x"))
    with _harness.Records("renderer_overhead", args, {"device": args.device}) as out:
        for _ in range(args.rounds):
            for n in args.spheres or [1000]:
                measure(out, n, width, height, args.device, args.frames)
    return 0


if __name__ == "__main__":
    sys.exit(main())
