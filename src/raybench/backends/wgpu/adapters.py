"""Which wgpu adapter to run on, and a device with the limits the tracer needs.

Without a name, only a GPU (discrete, then integrated) is chosen: a CPU
Vulkan or OpenGL driver (lavapipe/llvmpipe, SwiftShader) works, but is no
GPU, and a benchmark or `auto` that silently ran on one would mislead. Such an
adapter is used when it is named: adapter="llvmpipe" (--adapter llvmpipe)
picks the first adapter whose name contains that text, or whose backend it
names ("vulkan").
"""

from __future__ import annotations

import contextlib
import functools
import os
import sys
import tempfile
from dataclasses import dataclass

from ...errors import RaybenchError, shown

GPU_TYPES = ("DiscreteGPU", "IntegratedGPU")
# Among adapters of one type: the native APIs first, OpenGL (compute through GLES, fewer features) last.
BACKEND_ORDER = ("Vulkan", "Metal", "D3D12", "OpenGL")
# Limits the tracer may need beyond WebGPU's defaults; asked for up to what the adapter has.
LIMITS = (
    "max-compute-invocations-per-workgroup",
    "max-compute-workgroup-size-x",
    "max-compute-workgroup-size-y",
    "max-storage-buffer-binding-size",
    "max-buffer-size",
    "max-texture-dimension-2d",
)


@contextlib.contextmanager
def native_stderr_captured():
    """Collect what is written to file descriptor 2 meanwhile: the graphics
    drivers probed for an adapter print there directly, past sys.stderr."""
    sys.stderr.flush()
    saved = os.dup(2)
    captured = {"text": ""}
    with tempfile.TemporaryFile() as tmp:
        os.dup2(tmp.fileno(), 2)
        try:
            yield captured
        finally:
            sys.stderr.flush()
            os.dup2(saved, 2)
            os.close(saved)
            tmp.seek(0)
            captured["text"] = tmp.read().decode(errors="replace")


@dataclass(frozen=True)
class Adapter:
    name: str
    backend: str  # Vulkan, Metal, D3D12, OpenGL
    type: str  # DiscreteGPU, IntegratedGPU, CPU, VirtualGPU, Unknown
    adapter: object  # the wgpu GPUAdapter

    @property
    def is_gpu(self) -> bool:
        return self.type in GPU_TYPES

    def describe(self) -> dict:
        return {"name": self.name, "backend": self.backend, "type": self.type}

    def label(self) -> str:
        return f"{self.name} ({self.backend}, {self.type})"

    def rank(self) -> tuple[int, int]:
        kind = GPU_TYPES.index(self.type) if self.is_gpu else len(GPU_TYPES)
        backend = BACKEND_ORDER.index(self.backend) if self.backend in BACKEND_ORDER else len(BACKEND_ORDER)
        return kind, backend


@functools.cache
def found() -> tuple[Adapter, ...]:
    """Every adapter wgpu finds, best first (probed once per process: it takes
    a second, and the drivers' chatter on stderr is dropped)."""
    try:
        import wgpu
    except ImportError:
        return ()
    try:
        with native_stderr_captured():
            adapters = wgpu.gpu.enumerate_adapters_sync()
    except Exception:  # noqa: BLE001 - no driver at all is "none found", not a crash
        return ()
    out = [describe_raw(a) for a in adapters]
    return tuple(sorted(out, key=Adapter.rank))


def listing(adapters) -> str:
    return "; ".join(a.label() for a in adapters) or "none"


def gpu_present() -> bool:
    return any(a.is_gpu for a in found())


def choose(name: str | None = None) -> Adapter:
    """The adapter to trace on: the best GPU, or the best one matching name."""
    adapters = found()
    if name is None:
        gpus = [a for a in adapters if a.is_gpu]
        if gpus:
            return gpus[0]
        hint = (
            f"; a CPU adapter is used only when named: add --adapter {_short(adapters[0].name)!r}"
            if adapters
            else "; install a Vulkan, Metal or D3D12 driver"
        )
        raise RaybenchError(f"device wgpu: no GPU adapter (found: {listing(adapters)}){hint}")
    if not isinstance(name, str) or not name.strip():
        raise RaybenchError(f"adapter: must be a non-empty name, got {shown(name)}")
    needle = name.strip().lower()
    matches = [a for a in adapters if needle in a.name.lower() or needle == a.backend.lower()]
    if not matches:
        raise RaybenchError(f"adapter: none matches {name!r} (found: {listing(adapters)}); give part of one's name")
    return matches[0]


def _short(name: str) -> str:
    return name.split(" ")[0]


def device_requirements(adapter) -> dict:
    """request_device's arguments for a GPUAdapter: its higher limits (the
    thesis's 32x32 workgroup needs 1024 invocations where WebGPU's default is
    256), and timestamp queries and subgroups (the BVH's packet walk) where it
    has them."""
    limits = {k: adapter.limits[k] for k in LIMITS if k in adapter.limits}
    features = [f for f in ("timestamp-query", "subgroup") if f in adapter.features]
    return {"required_features": features, "required_limits": limits}


def request_device(adapter: Adapter):
    """A device on adapter, with device_requirements()."""
    failure = None
    with native_stderr_captured():
        try:
            device = adapter.adapter.request_device_sync(**device_requirements(adapter.adapter))
        except Exception as exc:  # noqa: BLE001
            failure = exc
    if failure is not None:
        raise RaybenchError(f"device wgpu: {adapter.label()} gave no device ({' '.join(str(failure).split())})")
    return device


def describe_raw(adapter) -> Adapter:
    """An Adapter for a GPUAdapter obtained elsewhere (the viewer's, which can draw to its window)."""
    return Adapter(
        adapter.info["device"] or adapter.info["description"] or "unknown",
        adapter.info["backend_type"],
        adapter.info["adapter_type"],
        adapter,
    )
