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


KERNELS = ("fast", "simple")
# Threads per block the fast CUDA kernel can always launch: its per-thread rays
# take registers, and 256 threads x 255 registers (the most a thread can have)
# fit the 64K registers of every CUDA multiprocessor. 32x32 can fail with
# CUDA_ERROR_LAUNCH_OUT_OF_RESOURCES.
FAST_MAX_THREADS = 256


def check_kernel(kernel, constant_count: bool) -> str:
    """The kernel's name, checked: "simple" (the thesis's loop, one pixel at a
    time) or "fast" (rays grouped, certain misses culled; the same pixels)."""
    if kernel not in KERNELS:
        raise RaybenchError(f"kernel: must be one of {', '.join(KERNELS)}, got {shown(kernel)}")
    if constant_count and kernel != "simple":
        raise RaybenchError("constant_count: applies to the simple kernel only; add kernel='simple' (--kernel simple)")
    return kernel


ACCELS = ("bvh", "none")
# Where a GPU's tree is built (cuda, wgpu): "host" (raybench.bvh's binned SAH
# tree, uploaded) or "gpu" (the LBVH of backends.cuda.build or
# backends.wgpu.build, built where it is walked).
BUILDS = ("host", "gpu")


def check_build(build, accel: str, default: str) -> str | None:
    """The build for a tracer of accel (None for brute force, which builds nothing)."""
    if build is None:
        return default if accel == "bvh" else None
    if accel != "bvh":
        raise RaybenchError("build: applies to the BVH only (accel='bvh'), not to brute force")
    if build not in BUILDS:
        raise RaybenchError(f"build: must be one of {', '.join(BUILDS)}, got {shown(build)}")
    return build


def check_accel(accel, kernel, brute_force_options: dict) -> tuple[str, str | None]:
    """(accel, kernel), checked. accel "bvh" walks a bounding volume hierarchy;
    "none" tests every sphere with the chosen kernel (default "fast"). The
    kernel and the options of the brute-force kernels (brute_force_options:
    name -> given) mean nothing to the BVH walk: asking for one without an
    accel implies accel "none"; asking for one with accel "bvh" is an error."""
    given = [name for name, on in brute_force_options.items() if on]
    if kernel is not None:
        given.insert(0, "kernel")
    if accel is None:
        accel = "none" if given else "bvh"
    if accel not in ACCELS:
        raise RaybenchError(f"accel: must be one of {', '.join(ACCELS)}, got {shown(accel)}")
    if accel == "bvh":
        if given:
            raise RaybenchError(
                f"{given[0]}: applies to brute force only (accel='none', --accel none), not to the BVH walk"
            )
        return accel, None
    return accel, "fast" if kernel is None else kernel


def check_bvh_fits(device: str, spheres: int, available: float, per_sphere: int, pixel_bytes_needed: int = 0) -> None:
    """A BVH of `spheres` spheres (per_sphere bytes each, at most) and the
    frame must fit in what the device has free."""
    need = max(spheres, 1) * per_sphere + pixel_bytes_needed
    if need > available:
        raise RaybenchError(
            f"bvh: {spheres:,} spheres need {_bytes(need)} for the BVH and the frame, "
            f"more than the {_bytes(available)} available on the {device}; "
            "use fewer spheres or a smaller size"
        )


def _bytes(n: float) -> str:
    return f"{n / 2**30:.2f} GiB" if n >= 2**30 else f"{n / 2**20:.1f} MiB"


# The GPU backends' two BVH walks: a ray at a time (kernels.traverse, the
# CPU's code), or a group of pixels' rays as one packet, which visits a node
# if any of its rays enters it (cuda: a block's rays, voting with its
# barriers; wgpu: a subgroup's, voting with subgroup operations). Each backend
# says which it takes by default.
WALKS = ("ray", "packet")


def check_walk(walk, accel: str) -> str | None:
    if walk is None:
        return None
    if accel != "bvh":
        raise RaybenchError("walk: applies to the BVH walk only (accel='bvh'), not to brute force")
    if walk not in WALKS:
        raise RaybenchError(f"walk: must be one of {', '.join(WALKS)}, got {shown(walk)}")
    return walk


SCHEDULES = ("wavefront", "pixel")


def check_schedule(schedule, whitted) -> str | None:
    """How Whitted's rays are spread over threads: "wavefront" (the default:
    a bounce's rays of every pixel at once, a stage a kernel; wavefront.py)
    or "pixel" (a thread traces its pixel's whole tree of rays). None for the
    thesis's shading, whose only rays are the primary ones."""
    if whitted is None:
        if schedule is not None:
            raise RaybenchError(f"schedule {shown(schedule)}: applies to Whitted shading only")
        return None
    if schedule is None:
        return "wavefront"
    if schedule not in SCHEDULES:
        raise RaybenchError(f"schedule: must be one of {', '.join(SCHEDULES)}, got {shown(schedule)}")
    return schedule


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
# WORKER_BYTES (its Python, NumPy, Numba and Dask: 244 MiB measured after a frame).
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
