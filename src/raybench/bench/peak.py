"""Measured FP32 peak of each processor: a long loop of independent fused
multiply-adds, the best any kernel could do on this machine.

The rates in machine.py are computed from the spec sheet (cores x clock x
lanes x 2); these are measured, so the floor in docs/notes/floors.md and the
"fraction of peak" of a ray tracer rest on what the chip really sustains
(turbo clocks, AVX-512 down-clocking, a shared virtual machine).
"""

from __future__ import annotations

import time
from concurrent.futures import ThreadPoolExecutor

import numpy as np

from ..host import usable_cores

CHAINS = 64  # CPU: independent accumulators, enough to hide FMA latency
UNROLL = 8  # GPU: 8 chains x 8 per loop trip
FLOP_PER_FMA = 2


def _cpu_kernel():
    from numba import njit

    # fastmath lets LLVM fuse a*b+c into one FMA and pack the 64 chains into
    # SIMD registers; the arithmetic is meaningless, only its rate counts
    @njit(fastmath=True, nogil=True, cache=True)
    def fma_chains(n, b, c):
        acc = np.empty(CHAINS, np.float32)
        for k in range(CHAINS):
            acc[k] = np.float32(k) * np.float32(1e-3)
        for _ in range(n):
            for k in range(CHAINS):
                acc[k] = acc[k] * b + c
        return acc.sum()

    return fma_chains


def cpu_peak(threads: int | None = None, seconds: float = 1.0) -> dict:
    """FP32 GFLOP/s of `threads` threads (default: one per logical CPU), each
    running FMA chains; the best of three runs."""
    threads = threads or usable_cores()
    kernel = _cpu_kernel()
    b, c = np.float32(0.999), np.float32(1e-4)
    kernel(1, b, c)
    n = 1000
    while True:  # size the loop to about `seconds`
        t = time.perf_counter()
        kernel(n, b, c)
        dt = time.perf_counter() - t
        if dt > 0.05:
            break
        n *= 4
    n = max(1, int(n * seconds / dt))
    best = 0.0
    with ThreadPoolExecutor(threads) as pool:
        for _ in range(3):
            t = time.perf_counter()
            list(pool.map(lambda _: kernel(n, b, c), range(threads)))
            dt = time.perf_counter() - t
            best = max(best, threads * n * CHAINS * FLOP_PER_FMA / dt / 1e9)
    return {"device": "cpu", "threads": threads, "fp32_gflops": best}


def cuda_peak(seconds: float = 0.5) -> dict:
    """FP32 GFLOP/s of the first CUDA GPU: every thread runs 8 independent FMA
    chains, enough blocks to fill every multiprocessor many times over; timed
    with CUDA events; the best of three launches."""
    from numba import cuda

    @cuda.jit(fastmath=True)
    def fma_chains(n, b, c, out):
        i = cuda.grid(1)
        f = np.float32(i) * np.float32(1e-9)
        a0, a1, a2, a3 = f, f + np.float32(1), f + np.float32(2), f + np.float32(3)
        a4, a5, a6, a7 = f + np.float32(4), f + np.float32(5), f + np.float32(6), f + np.float32(7)
        for _ in range(n):
            for _ in range(UNROLL):  # a constant trip count: unrolled, so the loop's own instructions are few
                a0 = a0 * b + c
                a1 = a1 * b + c
                a2 = a2 * b + c
                a3 = a3 * b + c
                a4 = a4 * b + c
                a5 = a5 * b + c
                a6 = a6 * b + c
                a7 = a7 * b + c
        # stored, so the compiler cannot drop the loop
        out[i] = a0 + a1 + a2 + a3 + a4 + a5 + a6 + a7

    device = cuda.get_current_device()
    block = 256
    blocks = device.MULTIPROCESSOR_COUNT * 32
    out = cuda.device_array(blocks * block, np.float32)
    b, c = np.float32(0.999), np.float32(1e-4)
    start, stop = cuda.event(), cuda.event()

    def launch(n):
        start.record()
        fma_chains[blocks, block](n, b, c, out)
        stop.record()
        stop.synchronize()
        return cuda.event_elapsed_time(start, stop) / 1e3

    launch(1)
    n = 256
    while (dt := launch(n)) < 0.02:
        n *= 4
    n = max(1, int(n * seconds / dt))
    best = 0.0
    for _ in range(3):
        dt = launch(n)
        best = max(best, blocks * block * n * UNROLL * 8 * FLOP_PER_FMA / dt / 1e9)
    return {
        "device": "cuda",
        "name": device.name.decode() if isinstance(device.name, bytes) else device.name,
        "fp32_gflops": best,
    }
