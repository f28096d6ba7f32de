"""What a numba-cuda kernel launch costs the host, split in its parts: an
empty kernel of 1, 4 or 12 device-array arguments launched N times from
Python, timed three ways (medians of --rounds, microseconds a launch):

  dispatch   kernel[grid, block](*args): numba-cuda's whole path
  launch     the compiled kernel's own launch(args, ...): no dispatch (typing
             the arguments, choosing the overload)
  prepare    the arguments' conversion alone (_prepare_args, as launch does
             it before the driver call): no launch
  prepared   cuda.core's launch of the kernel with the arguments converted
             once, before the loop: what a launch costs without numba-cuda

The GPU builder (backends/cuda/build.py) launches 20 kernels a build, so
these say how much of a small scene's build is the host's
(docs/startup.md#a-launchs-arguments-converted-once-leases-y3-and-y4). Needs a CUDA GPU.

    python benchmarks/launch_overhead.py --launches 2000 --rounds 5
"""

import argparse
import json
import statistics
import sys
import time

import numpy as np
from cuda.core import LaunchConfig, launch
from numba import cuda
from numba.cuda.cudadrv import driver


@cuda.jit
def one(a):
    pass


@cuda.jit
def four(a, b, c, d):
    pass


@cuda.jit
def twelve(a, b, c, d, e, f, g, h, i, j, k, m):
    pass


def per_launch_us(fn, launches: int, rounds: int) -> float:
    times = []
    for _ in range(rounds):
        cuda.synchronize()
        start = time.perf_counter()
        for _ in range(launches):
            fn()
        cuda.synchronize()
        times.append((time.perf_counter() - start) / launches * 1e6)
    return round(statistics.median(times), 2)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--launches", type=int, default=2000)
    parser.add_argument("--rounds", type=int, default=5)
    args = parser.parse_args()
    arrays = [cuda.to_device(np.zeros(1024, np.float32)) for _ in range(12)]
    stream = driver._to_core_stream(0)  # the default stream, as numba-cuda hands it to cuda.core
    config = LaunchConfig(grid=1, block=32)
    for kernel, count in ((one, 1), (four, 4), (twelve, 12)):
        given = arrays[:count]
        kernel[1, 32](*given)  # compile
        compiled = next(iter(kernel.overloads.values()))

        def prepare(compiled=compiled, given=given):
            retr, kernelargs = [], []
            for t, v in zip(compiled.argument_types, given):
                compiled._prepare_args(t, v, stream, retr, kernelargs)
            return kernelargs

        kernelargs = prepare()
        handle = compiled._codelibrary.get_cufunc().kernel

        row = {
            "arrays": count,
            "dispatch_us": per_launch_us(lambda k=kernel, g=given: k[1, 32](*g), args.launches, args.rounds),
            "launch_us": per_launch_us(
                lambda c=compiled, g=given: c.launch(g, (1, 1, 1), (32, 1, 1), stream, 0), args.launches, args.rounds
            ),
            "prepared_us": per_launch_us(
                lambda h=handle, a=kernelargs: launch(stream, config, h, *a), args.launches, args.rounds
            ),
            "prepare_us": per_launch_us(prepare, args.launches, args.rounds),
            "launches": args.launches,
            "rounds": args.rounds,
            "device": cuda.get_current_device().name.decode()
            if isinstance(cuda.get_current_device().name, bytes)
            else cuda.get_current_device().name,
        }
        print(json.dumps(row), flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
