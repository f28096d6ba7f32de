"""What a numba-cuda kernel launch costs the host, split in its parts: an empty kernel of 1, 4
or 12 device-array arguments launched --launches times from Python, timed four ways, one record
of the results schema's "parts" suite each (the time of one launch, a sample a round):

  launch-dispatch   kernel[grid, block](*args): numba-cuda's whole path
  launch-compiled   the compiled kernel's own launch(args, ...): no dispatch (typing the
                    arguments, choosing the overload)
  launch-convert    the arguments' conversion alone (backends/cuda/launch.convert_args, as
                    launch does it before the driver call): no launch
  launch-prepared   cuda.core's launch of the kernel with the arguments converted once, before
                    the loop (backends/cuda/launch.Prepared): what a launch costs without numba-cuda

The GPU builder (backends/cuda/build.py) launches 20 kernels a build, so these say how much of a
small scene's build is the host's
(docs/notes/startup.md#a-launchs-arguments-converted-once). Needs a CUDA GPU.

    PYTHONPATH=benchmarks python benchmarks/archive/launch_overhead.py --launches 2000 --rounds 5
"""

import argparse
import sys

import _harness
import numpy as np
from numba import cuda

from raybench.backends.cuda import launch


@cuda.jit
def one(a):
    pass


@cuda.jit
def four(a, b, c, d):
    pass


@cuda.jit
def twelve(a, b, c, d, e, f, g, h, i, j, k, m):
    pass


def per_launch_ms(fn, launches: int):
    """A variant of _harness.paired: the ms of one launch, over a loop of `launches`."""

    def loop():
        for _ in range(launches):
            fn()
        cuda.synchronize()

    def run() -> float:
        cuda.synchronize()
        return _harness.timings(loop, 1)[0] / launches

    return run


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--launches", type=int, default=2000)
    _harness.add_common(parser, frames=1, rounds=5)
    args = parser.parse_args()
    _harness.check_common(parser, args)
    arrays = [cuda.to_device(np.zeros(1024, np.float32)) for _ in range(12)]
    stream = launch.core_stream()
    with _harness.Records("launch_overhead", args, {"launches": args.launches}) as out:
        for kernel, count in ((one, 1), (four, 4), (twelve, 12)):
            given = arrays[:count]
            prepared = launch.Prepared(kernel, 1, 32, *given)  # compiled, its arguments converted once
            compiled = next(iter(kernel.overloads.values()))
            ways = {
                "launch-dispatch": lambda k=kernel, g=given: k[1, 32](*g),
                "launch-compiled": lambda c=compiled, g=given: c.launch(g, (1, 1, 1), (32, 1, 1), stream, 0),
                "launch-prepared": prepared,
                "launch-convert": lambda c=compiled, g=given: launch.convert_args(c, g, stream),
            }
            times = _harness.paired({n: per_launch_ms(w, args.launches) for n, w in ways.items()}, args.rounds)
            for name, samples in times.items():
                out.write(
                    _harness.part(
                        name, "cuda", samples, options={"arrays": count, "converted": prepared.converted},
                        values={"launches": args.launches},
                    )
                )  # fmt: skip
    return 0


if __name__ == "__main__":
    sys.exit(main())
