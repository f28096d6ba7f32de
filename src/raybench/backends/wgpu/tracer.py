"""The wgpu backend's Tracer: the compute pass on a device of its own, and the
frame read back to the host (texture -> RGB bytes packed on the GPU -> buffer
-> map) for trace(). With
accel "bvh" (the default, as on cpu and cuda) the pass walks the BVH; "none"
is the thesis's brute force, the simple kernel."""

from __future__ import annotations

import time

import numpy as np

from ...errors import RaybenchError
from ...host import host_available_bytes
from ...kernels.primitives import KINDS
from ...lighting import Shading
from ..contract import TracerBase, check_moved
from ..limits import HOST_PIXEL_BYTES, check_count, check_fits, check_size
from ..options import WgpuOptions
from . import adapters
from .compute import RAY_KINDS, Compute
from .pack import Packer, packed_bytes


def timestamp_period(device) -> float | None:
    """Nanoseconds per timestamp tick. wgpu-py does not expose it; wgpu-native
    does (wgpuQueueGetTimestampPeriod). None where it cannot be read: then
    frames are timed by the wall clock instead of guessing the unit."""
    try:
        from wgpu.backends.wgpu_native._api import libf

        period = float(libf.wgpuQueueGetTimestampPeriod(device.queue._internal))
    except Exception:  # noqa: BLE001 - another wgpu backend, or the private API moved
        return None
    return period if period > 0 else None


class Tracer(TracerBase):
    """Keeps the spheres, the frame texture and the readback buffers on the
    adapter's device between frames (the contract: backends.contract.Tracer)."""

    name = "wgpu"

    def __init__(
        self,
        spheres: np.ndarray,
        width: int,
        height: int,
        options: WgpuOptions | None = None,
        shading: Shading | None = None,
        primitive: str = "sphere",
    ):
        import wgpu

        options = self._options(options, shading)
        # the kind of primitive spheres' columns are (kernels/primitives' KINDS), checked by backends.tracer
        self.primitive = primitive
        check_size(width, height)
        self.adapter = adapters.choose(options.adapter)
        self.device = adapters.request_device(self.adapter)
        check_fits("host", width, height, 0, host_available_bytes(), HOST_PIXEL_BYTES)
        self.compute = Compute(
            self.device,
            spheres,
            width,
            height,
            options,
            shading,
            extra_texture_usage=wgpu.TextureUsage.TEXTURE_BINDING,
            primitive=primitive,
        )
        self.packer = Packer(self.device, self.compute.texture, width, height)
        self.options = options
        self.accel = options.accel
        self.build = self.compute.build  # where the BVH is built: "host" or "gpu"; None for brute force
        self.walk = self.compute.walk  # the BVH walk: "ray" or "packet"; None for brute force
        self.schedule = self.compute.schedule  # Whitted's: "wavefront" or "pixel"; None for the thesis's
        self.workgroup = self.compute.workgroup
        self.width, self.height, self.count = width, height, spheres.shape[1]
        self.image_read = self.device.create_buffer(
            size=packed_bytes(width, height), usage=wgpu.BufferUsage.COPY_DST | wgpu.BufferUsage.MAP_READ
        )
        self.hits_read = self.device.create_buffer(
            size=width * height * 4, usage=wgpu.BufferUsage.COPY_DST | wgpu.BufferUsage.MAP_READ
        )
        if shading is not None:
            self.rays_read = self.device.create_buffer(
                size=RAY_KINDS * 4, usage=wgpu.BufferUsage.COPY_DST | wgpu.BufferUsage.MAP_READ
            )
            self.ray_counts = np.zeros(RAY_KINDS, np.int64)
        self.image = np.empty((height, width, 3), np.uint8)
        self.hits = np.empty((height, width), np.int32)
        self.period_ns = timestamp_period(self.device) if self.compute.timestamps else None

    @property
    def build_s(self) -> float | None:
        """The last BVH build's seconds (None for brute force), for benchmark records."""
        return None if self.compute is None else self.compute.build_s

    def describe(self) -> dict:
        """The adapter, for result records and labels."""
        return {
            **self.adapter.describe(),
            "workgroup": list(self.workgroup),
            "timing": "timestamp-query" if self.period_ns else "wall clock",
        }

    def compile(self) -> float:
        return self.compute.compile()

    def update(self, spheres: np.ndarray) -> str | None:
        """The spheres moved: the contract's update (Compute.update: a refit
        or a build on the GPU with build "gpu", a build on the host else)."""
        if self.primitive != "sphere":
            noun = KINDS[self.primitive].NOUN
            raise RaybenchError(f"update: moves spheres; a scene of {noun} is traced as it was given")
        return self.compute.update(check_moved(spheres, self.compute.scene_spheres))

    def _count(self, count) -> int:
        return self.count if count is None else check_count(count, self.count)

    def _submit(self, basis, count, timed: bool, readback: bool) -> None:
        encoder = self.device.create_command_encoder()
        self.compute.encode(encoder, basis, count, timed=timed)
        if readback:
            self.encode_readback(encoder)
        self.device.queue.submit([encoder.finish()])

    def encode_readback(self, encoder) -> None:
        """Queue the frame's copy to the host on encoder: its RGB bytes packed on the GPU, then the
        image, the hits (and the ray counts) into the buffers that fetching maps."""
        self.packer.encode(encoder)
        encoder.copy_buffer_to_buffer(self.packer.packed, 0, self.image_read, 0, self.image_read.size)
        encoder.copy_buffer_to_buffer(self.compute.hits, 0, self.hits_read, 0, self.width * self.height * 4)
        if self.ray_counts is not None:
            encoder.copy_buffer_to_buffer(self.compute.rays, 0, self.rays_read, 0, RAY_KINDS * 4)

    def _fetch(self) -> tuple[np.ndarray, np.ndarray]:
        """Map the readback buffers (waits for the GPU) into self.image and self.hits."""
        import wgpu

        for buffer in (self.image_read, self.hits_read):
            buffer.map_sync(wgpu.MapMode.READ)
        try:
            # straight copies out of mapped memory: the image's bytes packed on the GPU (pack.py)
            self.image.reshape(-1)[...] = np.frombuffer(
                self.image_read.read_mapped(copy=False), np.uint8, count=self.image.size
            )
            self.hits[...] = np.frombuffer(self.hits_read.read_mapped(copy=False), np.int32).reshape(
                self.height, self.width
            )
        finally:
            self.image_read.unmap()
            self.hits_read.unmap()
        if self.ray_counts is not None:
            self.rays_read.map_sync(wgpu.MapMode.READ)
            try:
                self.ray_counts[:] = np.frombuffer(self.rays_read.read_mapped(copy=False), np.uint32)
            finally:
                self.rays_read.unmap()
        return self.image, self.hits

    def trace(self, basis: np.ndarray, count: int | None = None) -> tuple[np.ndarray, np.ndarray]:
        """Trace a frame of the first `count` spheres (default all) into
        self.image and self.hits, which are reused between frames."""
        self._submit(basis, self._count(count), timed=False, readback=True)
        if not self._settled():
            return self.trace(basis, count)
        return self._fetch()

    def timed_trace(self, basis: np.ndarray, count: int | None = None) -> float:
        """trace(), returning the compute pass's time in ms: GPU timestamps where
        the adapter has them, else the wall time from submitting the pass alone
        to its completion (the readback is outside either way)."""
        count = self._count(count)
        if self.period_ns:
            self._submit(basis, count, timed=True, readback=True)
            if not self._settled():
                return self.timed_trace(basis, count)
            kernel_ms = self.compute.read_kernel_ms(self.period_ns)
        else:
            self.compute.compile()
            encoder = self.device.create_command_encoder()
            self.compute.encode(encoder, basis, count)
            self.compute.encode_fence(encoder)
            start = time.perf_counter()
            self.device.queue.submit([encoder.finish()])
            self.compute.wait()
            kernel_ms = (time.perf_counter() - start) * 1e3
            if not self._settled():
                return self.timed_trace(basis, count)
            encoder = self.device.create_command_encoder()
            self.encode_readback(encoder)
            self.device.queue.submit([encoder.finish()])
        self._fetch()
        return kernel_ms

    @property
    def wavefront(self):
        """The Wavefront that traces this tracer's Whitted frames, None where
        they are traced a pixel an invocation."""
        return self.compute.wavefront

    def _settled(self) -> bool:
        """Whether the last frame needs no second trace: False where the
        wavefront's queues were short for it (now made longer; waits for
        the frame)."""
        return self.compute.wavefront is None or not self.compute.wavefront.overflowed()

    def close(self) -> None:
        """wgpu releases the buffers and the device with the objects."""
        self.compute = None
