"""wgpu frames traced into the very texture the window draws: the thesis's
GPU pipeline, SPHERE ARRAY -> BUFFER -> CALCULATE ON GPU -> TEXTURE -> quad,
with no copy of the frame in either direction.

The compute pass (the wgpu backend's Compute, on the window's own device)
and the quad's render pass are recorded into one command buffer by the
window; this module keeps the Compute for the current scene, size, options
and shading, and reads back how long the pass took and, under Whitted
shading, the rays it counted (16 bytes: the frame itself is never copied).
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

from ..backends.limits import check_count
from ..backends.options import checked
from ..backends.wgpu.compute import RAY_KINDS, Compute
from ..backends.wgpu.tracer import timestamp_period
from ..layout import KINDS


@dataclass(frozen=True)
class DrawnFrame:
    """A frame that exists only in the window's texture: what the viewer needs
    to know of it (Frame's width, height and device), without its pixels."""

    width: int
    height: int
    device: str
    adapter: str  # e.g. "llvmpipe (LLVM 15.0.6, 256 bits) (Vulkan, CPU)"
    rays: dict | None = None  # Whitted shading: the rays cast by kind, as Frame.rays; None under the thesis's


class InWindowTracer:
    """The wgpu backend on the window's device; one Compute at a time."""

    def __init__(self, device, adapter):
        self.device = device
        self.adapter = adapter  # adapters.Adapter
        self.period_ns = timestamp_period(device) if "timestamp-query" in device.features else None
        self.compute = None
        self._key = None
        self._scene = None
        self._started = 0.0
        self._rays_read = None  # where a Whitted pass's ray counts are copied, to be read back
        self._traced = None  # the last frame's camera basis and sphere count, to trace it again

    def prepare(self, request) -> float | None:
        """Make the Compute this request needs, if it is not the one held; the
        seconds its pipeline took to build (None if it was already there)."""
        # The adapter option chose the window's adapter; the rest are the backend's.
        options = {k: v for k, v in request.options.items() if k != "adapter"}
        key = (id(request.scene), id(request.shading), request.width, request.height, tuple(sorted(options.items())))
        if key == self._key:
            return None
        self.compute, self._key, self._scene = None, None, None
        import wgpu

        # checked as the Tracer's are; a frame of another sphere count (+, -, the ramp) gets its tree in encode()
        traced = request.scene.traced()  # the spheres, or a mesh scene's triangles
        compute = Compute(
            self.device,
            traced.buffer(),
            request.width,
            request.height,
            checked("wgpu", options, request.shading),
            request.shading,
            extra_texture_usage=wgpu.TextureUsage.TEXTURE_BINDING,
            primitive=traced.kind,
        )
        compile_s = compute.compile()
        if request.shading is not None and self._rays_read is None:
            usage = wgpu.BufferUsage.COPY_DST | wgpu.BufferUsage.MAP_READ
            self._rays_read = self.device.create_buffer(size=RAY_KINDS * 4, usage=usage)
        # The scene and shading are held with the key: their id()s must not be reused while the key is.
        self.compute, self._key, self._scene = compute, key, (request.scene, request.shading)
        return compile_s

    def encode(self, encoder, request) -> None:
        """Record the frame's compute pass (timed where the device has timestamps)."""
        count = check_count(request.count, self.compute.count)
        self._traced = (request.camera.basis(request.width, request.height), count)
        self.compute.encode(encoder, *self._traced, timed=self.period_ns is not None)
        if self.compute.shading is not None:
            encoder.copy_buffer_to_buffer(self.compute.rays, 0, self._rays_read, 0, RAY_KINDS * 4)
        if self.period_ns is None:
            self.compute.encode_fence(encoder)
        self._started = time.perf_counter()

    def elapsed_ms(self) -> float:
        """After the submission: the compute pass's GPU time, or where there are
        no timestamps, the wall time until the whole submission completed."""
        if self.period_ns is not None:
            return self.compute.read_kernel_ms(self.period_ns)
        self.compute.wait()
        return (time.perf_counter() - self._started) * 1e3

    def frame(self, request) -> DrawnFrame:
        """The frame, once its submission has completed (this waits for it).
        Where the wavefront's queues were short for it, it is traced again
        into the same texture with longer ones, which the next draw shows."""
        wavefront = self.compute.wavefront
        while wavefront is not None and wavefront.overflowed():
            encoder = self.device.create_command_encoder()
            self.compute.encode(encoder, *self._traced)
            encoder.copy_buffer_to_buffer(self.compute.rays, 0, self._rays_read, 0, RAY_KINDS * 4)
            self.compute.encode_fence(encoder)
            self.device.queue.submit([encoder.finish()])
            self.compute.wait()
        return DrawnFrame(request.width, request.height, "wgpu", self.adapter.label(), self._read_rays(request))

    def _read_rays(self, request) -> dict | None:
        """Under Whitted shading, the rays the pass counted, by kind."""
        if request.shading is None:
            return None
        import wgpu

        self._rays_read.map_sync(wgpu.MapMode.READ)
        try:
            counts = np.frombuffer(self._rays_read.read_mapped(copy=False), np.uint32).tolist()
        finally:
            self._rays_read.unmap()
        return dict(zip(KINDS, counts))
