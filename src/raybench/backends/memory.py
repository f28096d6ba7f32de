"""The check that a frame fits on a device before anything is allocated."""

from ..errors import RaybenchError

MAX_SIDE = 65536
# Per pixel: 3 colour bytes and a 4-byte hit index. Per sphere: 7 float32.
PIXEL_BYTES = 3 + 4
SPHERE_BYTES = 7 * 4


def check_size(width, height) -> None:
    for name, value in (("width", width), ("height", height)):
        if isinstance(value, bool) or not isinstance(value, int) or not 1 <= value <= MAX_SIDE:
            raise RaybenchError(f"size: {name} must be an integer from 1 to {MAX_SIDE}, got {value!r}")


def check_fits(device: str, width: int, height: int, spheres: int, available: float) -> None:
    check_size(width, height)
    need = width * height * PIXEL_BYTES + spheres * SPHERE_BYTES
    if need > available:
        raise RaybenchError(f"size: {width}x{height} with {spheres:,} spheres needs {need / 2**30:.2f} GiB, "
                            f"more than the {available / 2**30:.2f} GiB available on the {device}; choose a smaller size")
