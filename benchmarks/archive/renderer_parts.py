"""Where Renderer.render's time goes over its Tracer's trace(), warm, 1680x1050, at 1,000 and
100,000 spheres, --rounds rounds of --frames frames each, the parts taken in turn: the trace;
the trace into two pairs of arrays taken in turn, as a Renderer hands them over; render() with
and without hits; Camera.basis; and the kernel's own time where the device has one (cuda). One
record of the results schema's "parts" suite a part and size (quantity "renderer-" and the
part's name).

    PYTHONPATH=benchmarks python benchmarks/archive/renderer_parts.py --device cuda
"""

import argparse
import sys

import _harness

import raybench

WIDTH, HEIGHT = 1680, 1050


def parts(out, device: str, n: int, frames: int, rounds: int) -> None:
    scene = raybench.random_spheres(n, seed=0)
    camera = raybench.Camera()
    basis = camera.basis(WIDTH, HEIGHT)
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
            "trace-swapped-pairs": trace_swapped,
            "render": lambda: renderer.render(camera),
            "render-no-hits": lambda: renderer.render(camera, hits=False),
            "basis": lambda: camera.basis(WIDTH, HEIGHT),
        }
        variants = {name: (lambda call=call: _harness.timings(call, frames)) for name, call in ways.items()}
        times = _harness.paired(variants, rounds)
        kernel = [tracer.timed_trace(basis) for _ in range(frames * rounds)]
        if kernel[0] is not None:
            times["kernel"] = kernel
        for name, samples in times.items():
            out.write(_harness.part(f"renderer-{name}", device, samples, spheres=n, width=WIDTH, height=HEIGHT))


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--device", default="cpu")
    parser.add_argument("--spheres", type=int, action="append", help="default: 1000 and 100000")
    _harness.add_common(parser, frames=41, rounds=2)
    args = parser.parse_args()
    _harness.check_common(parser, args)
    with _harness.Records("renderer_parts", args, {"device": args.device}) as out:
        for n in args.spheres or [1_000, 100_000]:
            parts(out, args.device, n, args.frames, args.rounds)
    return 0


if __name__ == "__main__":
    sys.exit(main())
