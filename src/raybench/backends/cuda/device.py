"""Whether numba-cuda finds a CUDA device here, and which."""

from __future__ import annotations

from numba import config, cuda

from ...errors import RaybenchError


def simulated() -> bool:
    return bool(config.ENABLE_CUDASIM)


def available() -> bool:
    return cuda.is_available()


def reason() -> str:
    """Why numba-cuda finds no device, in its words on one line."""
    return " ".join((cuda.cuda_error() or "no CUDA device was found").split())


def unavailable_reason() -> str:
    return (
        "device cuda: no usable NVIDIA GPU (numba-cuda looked for the CUDA driver and a CUDA device: "
        f"{reason()}); use --device cpu"
    )


def require() -> None:
    if not available():
        raise RaybenchError(unavailable_reason())


def description() -> str:
    require()
    if simulated():
        return "cuda (numba's CUDA simulator)"
    dev = cuda.get_current_device()
    name = dev.name.decode() if isinstance(dev.name, bytes) else dev.name
    return f"cuda ({name})"
