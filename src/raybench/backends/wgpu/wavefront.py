"""Whitted shading on wgpu by ray, not by pixel: wavefront.wgsl's stages,
each a dispatch over a queue, a wave a bounce (cuda's wavefront, in WGSL).

A frame is one compute pass: the state zeroed and the primary rays into the
first queue, then for each bounce up to the depth extend (closest hits),
shade (shadow rays into the shadow queue, children into the next wave's
queue) and shadow (any hit), and a dispatch that moves the wave on; then the
pixels' summed light into the frame's texture. The queues' counts stay on
the GPU: a stage reads how many rays its queue holds where it runs. A queue
that would overflow keeps the count of the rays it was asked to hold; the
frame is then traced again with queues that fit (the Tracer asks
overflowed()), so no ray is lost.

Its pipelines share one explicit bind-group layout: every binding of the
pixel program's Whitted shader, and the wavefront's four (queues' floats,
their ints, the state and the pixels' sums as atomic words, the sizes).
"""

from __future__ import annotations

import numpy as np

from ...errors import RaybenchError
from ...kernels import wavefront as stages
from . import shader

GROUP = 64  # wavefront.wgsl's WF_GROUP
# Workgroups a stage is dispatched on: each invocation loops over its share
# of the queue (cuda's wavefront measured 32 blocks a multiprocessor best;
# wgpu does not say how many a GPU has, so a number that fills large ones).
GROUPS = 4096
RAYS_A_PIXEL = 1
SHADOWS_A_PIXEL = 2
MAX_WAVES = shader.MAX_WAVES
SHADOW_BASE = MAX_WAVES
OVERFLOW = 2 * MAX_WAVES
STATE = 2 * MAX_WAVES + 2  # words before the pixels' sums: ray counts, shadow counts, overflow, wave
WAVES_BYTES = 32
ENTRIES = ("main_wf_start", "main_wf_primary", "main_wf_extend", "main_wf_shade", "main_wf_shadow",
           "main_wf_advance", "main_wf_finish")  # fmt: skip


def _grown(needed: int, capacity: int) -> int:
    while capacity < needed:
        capacity *= 2
    return capacity


class Wavefront:
    """The wavefront's pipelines, queues and sums for one Compute (its
    device, spheres, tree, shading, texture and hits)."""

    def __init__(self, compute, depth: int):
        import wgpu

        self.compute, self.depth = compute, depth
        device = compute.device
        self.device = device
        pixels = compute.width * compute.height
        self.pixels = pixels
        self.groups = min(GROUPS, max(1, -(-pixels // GROUP)))
        storage = wgpu.BufferUsage.STORAGE
        self.sums = device.create_buffer(
            size=(STATE + 6 * max(pixels, 1)) * 4, usage=storage | wgpu.BufferUsage.COPY_SRC
        )  # zeroed at creation; each frame's last dispatch zeroes what it read
        self.waves = device.create_buffer(size=WAVES_BYTES, usage=wgpu.BufferUsage.UNIFORM | wgpu.BufferUsage.COPY_DST)
        self.state_read = device.create_buffer(
            size=STATE * 4, usage=wgpu.BufferUsage.COPY_DST | wgpu.BufferUsage.MAP_READ
        )
        self.pipelines = None
        self.bind_group = None
        self.retraced = 0
        self._allocate(max(pixels * RAYS_A_PIXEL, GROUP), max(pixels * SHADOWS_A_PIXEL, GROUP))

    def _allocate(self, rays: int, shadows: int) -> None:
        import wgpu

        self.ray_capacity, self.shadow_capacity = rays, shadows
        floats = (2 * stages.RAY_ROWS + 2) * rays + stages.SHADOW_ROWS * shadows
        ints = (2 * stages.RAY_IDS + 1) * rays + stages.SHADOW_IDS * shadows
        limit = min(self.device.limits["max-storage-buffer-binding-size"], self.device.limits["max-buffer-size"])
        if max(floats, ints) * 4 > limit:
            raise RaybenchError(
                f"schedule 'wavefront': its queues ({max(floats, ints) * 4 / 2**20:.0f} MiB) exceed this device's "
                f"largest buffer ({limit / 2**20:.0f} MiB); use a smaller frame or schedule='pixel'"
            )
        self.floats = self.device.create_buffer(size=floats * 4, usage=wgpu.BufferUsage.STORAGE)
        self.ints = self.device.create_buffer(size=ints * 4, usage=wgpu.BufferUsage.STORAGE)
        self.bind_group = None

    def _layout(self):
        import wgpu

        compute = self.compute
        uniform = {"buffer": {"type": wgpu.BufferBindingType.uniform}}
        read = {"buffer": {"type": wgpu.BufferBindingType.read_only_storage}}
        write = {"buffer": {"type": wgpu.BufferBindingType.storage}}
        texture = {
            "storage_texture": {
                "access": wgpu.StorageTextureAccess.write_only,
                "format": wgpu.TextureFormat.rgba8unorm,
                "view_dimension": wgpu.TextureViewDimension.d2,
            }
        }
        kinds = {0: uniform, 1: read, 2: texture, 3: write, 7: read, 8: uniform, 9: write, 10: write, 11: write,
                 12: write, 13: uniform}  # fmt: skip
        if compute.tree is not None:
            kinds.update({4: read, 5: read, 6: read})
        entries = [{"binding": b, "visibility": wgpu.ShaderStage.COMPUTE, **kind} for b, kind in sorted(kinds.items())]
        return self.device.create_bind_group_layout(entries=entries)

    def compile(self) -> None:
        """The module and its pipelines, once."""
        if self.pipelines is not None:
            return
        compute = self.compute
        self.layout = self._layout()
        pipeline_layout = self.device.create_pipeline_layout(bind_group_layouts=[self.layout])
        module = self.device.create_shader_module(code=shader.source(compute.workgroup, compute.accel, "wavefront"))
        self.pipelines = {
            entry: self.device.create_compute_pipeline(
                layout=pipeline_layout, compute={"module": module, "entry_point": entry}
            )
            for entry in ENTRIES
        }

    def _bind(self) -> None:
        compute = self.compute
        entries = [
            {"binding": 0, "resource": {"buffer": compute.uniform}},
            {"binding": 1, "resource": {"buffer": compute.spheres}},
            {"binding": 2, "resource": compute.texture.create_view()},
            {"binding": 3, "resource": {"buffer": compute.hits}},
            {"binding": 7, "resource": {"buffer": compute.materials}},
            {"binding": 8, "resource": {"buffer": compute.lighting}},
            {"binding": 9, "resource": {"buffer": compute.rays}},
            {"binding": 10, "resource": {"buffer": self.floats}},
            {"binding": 11, "resource": {"buffer": self.ints}},
            {"binding": 12, "resource": {"buffer": self.sums}},
            {"binding": 13, "resource": {"buffer": self.waves}},
        ]
        if compute.tree is not None:
            entries += [
                {"binding": 4, "resource": {"buffer": compute.nodes}},
                {"binding": 5, "resource": {"buffer": compute.ordered}},
                {"binding": 6, "resource": {"buffer": compute.order}},
            ]
        self.bind_group = self.device.create_bind_group(layout=self.layout, entries=entries)
        self._bound_tree = compute.tree

    def encode(self, compute_pass) -> None:
        """A frame's dispatches into compute_pass (the frame uniform already written)."""
        self.compile()
        if self.bind_group is None or self._bound_tree is not self.compute.tree:
            self._bind()
        sizes = np.array([self.ray_capacity, self.shadow_capacity, self.pixels, 0, self.groups, 0, 0, 0], np.uint32)
        self.device.queue.write_buffer(self.waves, 0, sizes.tobytes())
        compute_pass.set_bind_group(0, self.bind_group)

        def run(entry: str, groups: int) -> None:
            compute_pass.set_pipeline(self.pipelines[entry])
            compute_pass.dispatch_workgroups(groups, 1, 1)

        run("main_wf_start", 1)
        run("main_wf_primary", self.groups)
        for _ in range(self.depth + 1):
            run("main_wf_extend", self.groups)
            run("main_wf_shade", self.groups)
            run("main_wf_shadow", self.groups)
            run("main_wf_advance", 1)
        run("main_wf_finish", self.groups)

    def encode_state_read(self, encoder) -> None:
        """Copy the frame's state words for overflowed() (after the pass)."""
        encoder.copy_buffer_to_buffer(self.sums, 0, self.state_read, 0, STATE * 4)

    def overflowed(self) -> bool:
        """Whether the last frame's queues were too short (waits for it); if
        so they are made long enough for it, to trace it again."""
        import wgpu

        self.state_read.map_sync(wgpu.MapMode.READ)
        try:
            state = np.frombuffer(self.state_read.read_mapped(), np.uint32).copy()
        finally:
            self.state_read.unmap()
        if not state[OVERFLOW]:
            return False
        rays = max(self.ray_capacity, int(state[: self.depth + 2].max()))
        shadows = max(self.shadow_capacity, int(state[SHADOW_BASE : SHADOW_BASE + self.depth + 1].max()))
        self._allocate(_grown(rays, self.ray_capacity), _grown(shadows, self.shadow_capacity))
        self.retraced += 1
        return True
