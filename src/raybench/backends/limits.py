"""Limits checked before anything is allocated or launched: sizes, memory, counts."""

import psutil

from ..errors import RaybenchError

MAX_SIDE = 65536
# Per pixel: 3 colour bytes and a 4-byte hit index, on the device; the host
# holds them twice (the tracer's buffers and the Frame's copy). Per sphere: 7 float32.
PIXEL_BYTES = 3 + 4
HOST_PIXEL_BYTES = 2 * PIXEL_BYTES
SPHERE_BYTES = 7 * 4


def check_size(width, height) -> None:
    for name, value in (("width", width), ("height", height)):
        if isinstance(value, bool) or not isinstance(value, int) or not 1 <= value <= MAX_SIDE:
            raise RaybenchError(f"size: {name} must be an integer from 1 to {MAX_SIDE}, got {value!r}")


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
        raise RaybenchError(f"sphere count: this kernel was compiled for exactly {loaded} spheres, got {count!r}")
    if isinstance(count, bool) or not isinstance(count, int) or not 0 <= count <= loaded:
        raise RaybenchError(f"sphere count: must be an integer from 0 to {loaded} (the spheres loaded), got {count!r}")
    return count


def host_available_bytes() -> int:
    return psutil.virtual_memory().available


KERNELS = ("fast", "simple")
# Threads per block the fast CUDA kernel can always launch: its per-thread rays
# take registers, and 256 threads x 255 registers (the most a thread can have)
# fit the 64K registers of every CUDA multiprocessor. 32x32 failed on an H100
# with CUDA_ERROR_LAUNCH_OUT_OF_RESOURCES.
FAST_MAX_THREADS = 256


def check_kernel(kernel, constant_count: bool) -> str:
    """The kernel's name, checked: "simple" (the thesis's loop, one pixel at a
    time) or "fast" (rays grouped, certain misses culled; the same pixels)."""
    if kernel not in KERNELS:
        raise RaybenchError(f"kernel: must be one of {', '.join(KERNELS)}, got {kernel!r}")
    if constant_count and kernel != "simple":
        raise RaybenchError("constant_count: applies to the simple kernel only; add kernel='simple' (--kernel simple)")
    return kernel


ACCELS = ("bvh", "none")


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
        raise RaybenchError(f"accel: must be one of {', '.join(ACCELS)}, got {accel!r}")
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
