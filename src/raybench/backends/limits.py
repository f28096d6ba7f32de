"""Limits checked before anything is allocated or launched: sizes, memory, counts."""

import math
import numbers

import numpy as np

from ..errors import RaybenchError, shown
from ..host import host_available_bytes, usable_cores

MAX_SIDE = 65536
# Per pixel: 3 colour bytes and a 4-byte hit index, on the device; the host
# holds them twice (the tracer's buffers and the Frame's copy). Per sphere: 7 float32.
PIXEL_BYTES = 3 + 4
HOST_PIXEL_BYTES = 2 * PIXEL_BYTES
SPHERE_BYTES = 7 * 4


def is_integer(value) -> bool:
    """An integer, NumPy's included; a bool is not one."""
    return isinstance(value, numbers.Integral) and not isinstance(value, (bool, np.bool_))


def check_size(width, height) -> tuple[int, int]:
    """(width, height) as Python ints, checked."""
    for name, value in (("width", width), ("height", height)):
        if not is_integer(value) or not 1 <= value <= MAX_SIDE:
            raise RaybenchError(f"size: {name} must be an integer from 1 to {MAX_SIDE}, got {shown(value)}")
    return int(width), int(height)


def check_rows(rows, height: int, align: int = 1) -> tuple[int, int]:
    """(first, end): rows first..end of a frame `height` rows high (a
    cluster's tile), first a multiple of align (cpu: its packets' height,
    where the whole frame's packets start)."""
    try:
        first, end = (int(r) for r in rows)
    except (TypeError, ValueError):
        raise RaybenchError(f"rows: must be (first, end), got {shown(rows)}") from None
    if not (0 <= first < end <= height and first % align == 0):
        raise RaybenchError(
            f"rows: must be (first, end) with 0 <= first < end <= {height} and first a multiple of {align}, "
            f"got {shown(rows)}"
        )
    return first, end


def check_fits(
    device: str, width: int, height: int, spheres: int, available: float, pixel_bytes: int = PIXEL_BYTES
) -> None:
    check_size(width, height)
    need = width * height * pixel_bytes + spheres * SPHERE_BYTES
    if need > available:
        raise RaybenchError(
            f"size: {width}x{height} with {spheres:,} spheres needs {need / 2**30:.2f} GiB, "
            f"more than the {available / 2**30:.2f} GiB available on the {device}; choose a smaller size"
        )


def check_count(count, loaded: int, constant: bool = False) -> int:
    """A frame may trace the first `count` of the spheres a tracer holds, never more:
    the kernels do not check bounds. A kernel compiled for a constant count traces
    exactly that many."""
    if constant and count != loaded:
        raise RaybenchError(f"sphere count: this kernel was compiled for exactly {loaded} spheres, got {shown(count)}")
    if not is_integer(count) or not 0 <= count <= loaded:
        raise RaybenchError(
            f"sphere count: must be an integer from 0 to {loaded} (the spheres loaded), got {shown(count)}"
        )
    return int(count)


def check_bvh_fits(
    device: str, spheres: int, available: float, per_sphere: int, pixel_bytes_needed: int = 0, noun: str = "spheres"
) -> None:
    """A BVH of `spheres` spheres (per_sphere bytes each, at most) and the
    frame must fit in what the device has free. noun: what the primitives
    are called (a mesh's "triangles")."""
    need = max(spheres, 1) * per_sphere + pixel_bytes_needed
    if need > available:
        raise RaybenchError(
            f"bvh: {spheres:,} {noun} need {_bytes(need)} for the BVH and the frame, "
            f"more than the {_bytes(available)} available on the {device}; "
            f"use fewer {noun} or a smaller size"
        )


def _bytes(n: float) -> str:
    return f"{n / 2**30:.2f} GiB" if n >= 2**30 else f"{n / 2**20:.1f} MiB"


# --- a cluster's: raybench.cluster and the command line check by these alike

CONNECT_TIMEOUT_S = (0.1, 3600.0)


def check_connect_timeout(timeout) -> float:
    """Seconds to try a scheduler's address: a finite number in CONNECT_TIMEOUT_S
    (Dask took NaN, and failed on it with a KeyError)."""
    low, high = CONNECT_TIMEOUT_S
    if (
        isinstance(timeout, (bool, np.bool_))
        or not isinstance(timeout, numbers.Real)
        or not math.isfinite(timeout)
        or not low <= timeout <= high
    ):
        raise RaybenchError(
            f"connect timeout: must be a number of seconds from {low:g} to {high:g}, got {shown(timeout)}"
        )
    return float(timeout)


# The embedded cluster's worker processes on this machine: beyond WORKERS_PER_CORE
# a core they only take turns on the same cores, and each holds about
# WORKER_BYTES, its Python, NumPy, Numba and Dask (docs/notes/scaling.md#cpu-workers-2-vcpus).
WORKERS_PER_CORE = 4
WORKER_BYTES = 256 * 2**20


def max_workers() -> tuple[int, str]:
    """The most worker processes an embedded cluster may start here, and why."""
    cores = usable_cores()
    by_cores = WORKERS_PER_CORE * cores
    by_memory = max(1, host_available_bytes() // WORKER_BYTES)
    if by_memory < by_cores:
        return int(
            by_memory
        ), f"each worker process takes about {_bytes(WORKER_BYTES)}, of the {_bytes(host_available_bytes())} available"
    return by_cores, f"{WORKERS_PER_CORE} a core, of the {cores} this process may use"


def check_worker_count(workers) -> int:
    """An embedded cluster's worker count: a whole number from 1 to max_workers()."""
    if not is_integer(workers) or workers < 1:
        raise RaybenchError(f"workers: must be a whole number >= 1, got {shown(workers)}")
    most, why = max_workers()
    if workers > most:
        raise RaybenchError(f"workers: at most {most} on this machine ({why}), got {int(workers):,}")
    return int(workers)
