"""Where Renderer.render's time goes over its Tracer's trace(), warm, 1680x1050,
at 1,000 and 100,000 spheres, two rounds of medians of 41 frames each: the
trace; the trace into two pairs of arrays taken in turn, as a Renderer hands
them over; render() with and without hits; Camera.basis; and the kernel's own
time where the device has one (cuda). One line of JSON a size.

    python benchmarks/renderer_parts.py --device cuda
"""

import argparse
import json
import statistics
import time

import raybench

WIDTH, HEIGHT = 1680, 1050


def median_ms(call, frames: int = 41) -> float:
    times = []
    for _ in range(frames):
        start = time.perf_counter()
        call()
        times.append((time.perf_counter() - start) * 1e3)
    return round(statistics.median(times), 3)


def parts(device: str, n: int) -> dict:
    scene = raybench.random_spheres(n, seed=0)
    camera = raybench.Camera()
    basis = camera.basis(WIDTH, HEIGHT)
    row = {"device": device, "spheres": n, "width": WIDTH, "height": HEIGHT}
    with raybench.Renderer(scene, WIDTH, HEIGHT, device=device) as renderer:
        tracer = renderer.tracer
        renderer.render(camera)
        tracer.trace(basis)
        own = tracer.image, tracer.hits
        pairs = [tuple(tracer.host_array(a.shape, a.dtype) for a in own) for _ in range(2)]
        turn = [0]

        def trace_swapped():
            tracer.image, tracer.hits = pairs[turn[0] % 2]
            turn[0] += 1
            tracer.trace(basis)
            tracer.image, tracer.hits = own

        ways = {
            "trace": lambda: tracer.trace(basis),
            "trace_swapped_pairs": trace_swapped,
            "render": lambda: renderer.render(camera),
            "render_no_hits": lambda: renderer.render(camera, hits=False),
            "basis": lambda: camera.basis(WIDTH, HEIGHT),
        }
        for _ in range(2):
            for name, call in ways.items():
                row.setdefault(f"{name}_ms", []).append(median_ms(call))
            kernel = [tracer.timed_trace(basis) for _ in range(21)]
            if kernel[0] is not None:
                row.setdefault("kernel_ms", []).append(round(statistics.median(kernel), 3))
    return row


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--device", default="cpu")
    args = parser.parse_args()
    for n in (1_000, 100_000):
        print(json.dumps(parts(args.device, n)), flush=True)


if __name__ == "__main__":
    main()
