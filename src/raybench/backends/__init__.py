"""The registry of backends: pick one by name, or "auto".

Backends import lazily: numba-cuda is only loaded when a GPU is asked about.
"""

from __future__ import annotations

import importlib

from ..errors import RaybenchError

DEVICES = ("cpu", "cuda")
CHOICES = ("auto",) + DEVICES
OPTIONS = {"cpu": ("threads", "constant_count", "kernel", "accel"),
           "cuda": ("block", "constant_count", "kernel", "rays", "tile", "accel")}


def module(name: str):
    if name not in DEVICES:
        raise RaybenchError(f"device: unknown device {name!r}; choose one of {', '.join(CHOICES)}")
    return importlib.import_module(f".{name}", __name__)


def cuda_available() -> bool:
    """A real CUDA GPU is usable (numba's simulator does not count)."""
    try:
        mod = module("cuda")
    except ImportError:
        return False
    return mod.available() and not mod.simulated()


def resolve(device: str) -> str:
    """The concrete device for a name: "auto" is cuda where a usable GPU is
    present, else cpu. Asking for cuda where there is none is an error, never a
    silent fallback; asking for it under NUMBA_ENABLE_CUDASIM=1 runs the simulator."""
    if device == "auto":
        return "cuda" if cuda_available() else "cpu"
    if device == "cuda":
        try:
            module("cuda").require()
        except ImportError as exc:
            raise RaybenchError(f"device cuda: numba-cuda is not installed ({exc}); "
                                "pip install numba-cuda, or use --device cpu") from None
        return "cuda"
    module(device)
    return device


def present() -> list[str]:
    """Every device usable on this machine."""
    return ["cpu"] + (["cuda"] if cuda_available() else [])


def tracer(device: str, spheres, width: int, height: int, **options):
    """A Tracer of the (resolved) device for this scene and size; options are
    the device's own (cpu: threads; cuda: block, rays, tile) and, on both,
    accel ("bvh", the default, or "none"), kernel and constant_count."""
    name = resolve(device)
    for key in options:
        if key not in OPTIONS[name]:
            allowed = ", ".join(OPTIONS[name])
            raise RaybenchError(f"option {key!r} does not apply to device {name} (its options: {allowed})")
    return module(name).Tracer(spheres, width, height, **options)
