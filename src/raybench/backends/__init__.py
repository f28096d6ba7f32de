"""The registry of backends: pick one by name, or "auto".

Backends import lazily: numba-cuda and wgpu are only loaded when a GPU is
asked about ("auto" asks about both, and loads numba-cuda only where NVIDIA's
driver library is present).
"""

from __future__ import annotations

import ctypes
import importlib
import os
import sys

from ..errors import RaybenchError, shown
from .options import NAMES, checked

DEVICES = ("cpu", "cuda", "wgpu")
CHOICES = ("auto",) + DEVICES
# Each device's options, by name: backends/options.py, where they are checked.
OPTIONS = NAMES


def module(name: str):
    if name not in DEVICES:
        raise RaybenchError(f"device: unknown device {name!r}; choose one of {', '.join(CHOICES)}")
    return importlib.import_module(f".{name}", __name__)


def _driver_candidates() -> list[str]:
    """Where numba-cuda looks for NVIDIA's driver library (its
    cudadrv.driver.locate_driver_and_loader): the names, then fixed folders."""
    if sys.platform == "win32":
        folders, names = ["\\windows\\system32"], ["nvcuda.dll"]
    elif sys.platform == "darwin":
        folders, names = ["/usr/local/cuda/lib"], ["libcuda.dylib"]
    else:
        folders, names = ["/usr/lib", "/usr/lib64"], ["libcuda.so", "libcuda.so.1"]
    return names + [os.path.join(folder, name) for folder in folders for name in names]


def _cuda_driver_loads() -> bool:
    """NVIDIA's driver library loads from where numba-cuda would load it.
    Without it numba-cuda finds no GPU either; asking this way is all but
    free, where importing numba-cuda to ask is not, which every "auto" on a
    machine without an NVIDIA GPU paid (the figures:
    docs/notes/startup.md#the-builder-compiled-only-where-a-scene-needs-it)."""
    for candidate in _driver_candidates():
        try:
            ctypes.CDLL(candidate)
        except OSError:
            continue
        return True
    return False


def cuda_available() -> bool:
    """A real CUDA GPU is usable (numba's simulator does not count)."""
    if not _cuda_driver_loads():
        return False
    try:
        mod = module("cuda")
    except ImportError:
        return False
    return mod.available() and not mod.simulated()


def wgpu_gpu_available() -> bool:
    """wgpu finds a GPU adapter (a CPU driver such as lavapipe does not count)."""
    return module("wgpu").gpu_present()


def resolve(device: str, adapter: str | None = None) -> str:
    """The concrete device for a name: "auto" is cuda where a usable NVIDIA GPU
    is present, else wgpu where it finds a GPU, else cpu. Asking for cuda or
    wgpu where there is none is an error, never a silent fallback; asking for
    cuda under NUMBA_ENABLE_CUDASIM=1 runs the simulator. adapter: the wgpu
    adapter's name, if one is named (a CPU driver is used only then)."""
    if not isinstance(device, str):  # (an array's == is element-wise: a ValueError from NumPy)
        raise RaybenchError(f"device: must be one of {', '.join(CHOICES)}, got {shown(device)}")
    if device == "auto":
        if cuda_available():
            return "cuda"
        return "wgpu" if wgpu_gpu_available() else "cpu"
    if device == "wgpu":
        module("wgpu").require(adapter)
        return "wgpu"
    if device == "cuda":
        try:
            module("cuda").require()
        except ImportError as exc:
            raise RaybenchError(
                f"device cuda: numba-cuda is not installed ({exc}); pip install numba-cuda, or use --device cpu"
            ) from None
        return "cuda"
    module(device)
    return device


def present() -> list[str]:
    """Every device usable on this machine."""
    return ["cpu"] + (["cuda"] if cuda_available() else []) + (["wgpu"] if wgpu_gpu_available() else [])


def tracer(device: str, spheres, width: int, height: int, shading=None, primitive: str = "sphere", **options):
    """A Tracer of the (resolved) device for this scene and size. primitive:
    the kind of primitive the columns of `spheres` are (kernels/primitives'
    KINDS): "sphere", Scene.spheres; "triangle", meshes.mesh_leaves' buffer
    or a meshes.Painted mesh (its buffer made where a device reads one),
    traced on every device; "mixed", spheres and triangles in one buffer
    (scene_meshes.mixed_leaves), traced on every device too ("auto" picks the
    cpu for both). options:
    the device's own (backends/options.py: cpu's threads and tree_width;
    cuda's block, rays, staged, trip, walk, build and the GPU build's
    variants; wgpu's workgroup, adapter, walk and build; on every device
    accel, "bvh" (the default) or "none", and brute force's kernel), checked
    there in one place. shading: the lighting.Shading of a Whitted frame,
    None for the thesis's shading."""
    if primitive != "sphere" and isinstance(device, str) and device == "auto":
        device = "cpu"  # auto: the cpu traces every kind
    name = resolve(device, options.get("adapter") if isinstance(device, str) and device == "wgpu" else None)
    from ..meshes import Painted

    painted = isinstance(spheres, Painted)
    if primitive != "sphere":
        _check_kind(name, spheres, primitive)
    if shading is not None:
        import numpy as np

        from ..lighting import Shading

        if not isinstance(shading, Shading):
            raise RaybenchError(f"shading: must be a raybench.lighting.Shading, got {type(shading).__name__}")
        shading.check(len(spheres) if painted else np.shape(spheres)[-1])
    if painted and name != "cpu":
        spheres = spheres.leaves()  # the GPUs trace a scene buffer: made here
    if primitive != "sphere":
        return module(name).Tracer(spheres, width, height, checked(name, options, shading), shading, primitive)
    return module(name).Tracer(spheres, width, height, checked(name, options, shading), shading)


# The devices that trace each kind of primitive other than the sphere.
KIND_DEVICES = {"triangle": ("cpu", "cuda", "wgpu"), "mixed": ("cpu", "cuda", "wgpu")}


def _check_kind(device: str, buffer, primitive: str) -> None:
    """Refuse, in one line, a kind of primitive other than the sphere on a
    device that cannot trace it yet, or a buffer without the rows its
    shading reads."""
    import numpy as np

    from ..kernels.primitives import KINDS

    if primitive not in KINDS:
        raise RaybenchError(f"primitive: must be one of {', '.join(KINDS)}, got {shown(primitive)}")
    if device not in KIND_DEVICES[primitive]:
        what = "scenes of spheres and meshes together are" if primitive == "mixed" else f"{primitive}s are"
        raise RaybenchError(f"device {device}: {what} traced on {', '.join(KIND_DEVICES[primitive])} only so far")
    from ..meshes import Painted

    if isinstance(buffer, Painted):
        if primitive != "triangle":
            raise RaybenchError(f"a painted mesh (meshes.Painted) is traced as primitive 'triangle', not {primitive!r}")
        return
    rows = KINDS[primitive].SCENE_ROWS
    if not (
        isinstance(buffer, np.ndarray)
        and buffer.dtype == np.float32
        and buffer.ndim == 2
        and buffer.shape[0] >= rows
        and buffer.flags.c_contiguous
    ):
        got = f"{buffer.shape} {buffer.dtype}" if isinstance(buffer, np.ndarray) else type(buffer).__name__
        raise RaybenchError(
            f"{primitive}s: a C-contiguous float32 buffer of at least {rows} rows (meshes.mesh_leaves), got {got}"
        )
