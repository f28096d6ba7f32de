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

A frame whose queues would not fit in the device's largest storage buffer
is traced in bands of rows (backends/bands.py): a compute pass a band, in
the same command buffer, each band's sizes copied into the uniform before
its pass and its state words copied out after it, so a banded frame is
still one submission and one read of the state. The pixels' sums are the
band's, indexed from its first pixel.

Its pipelines share one explicit bind-group layout: every binding of the
pixel program's Whitted shader, and the wavefront's four (queues' floats,
their ints, the state and the pixels' sums as atomic words, the sizes).
"""

from __future__ import annotations

import numpy as np

from ...kernels import wavefront as stages
from .. import bands
from . import shader

GROUP = 64  # wavefront.wgsl's WF_GROUP
# Workgroups a stage is dispatched on: each invocation loops over its share
# of the queue. wgpu does not say how many multiprocessors a GPU has, so a
# number that fills large ones several times over: the more invocations a
# stage has in flight, the less the GPU waits on the slowest at its end
# (measured: docs/notes/whitted.md#the-wavefronts-grid-issue-27).
GROUPS = 16384
RAYS_A_PIXEL = 1
SHADOWS_A_PIXEL = 2
MAX_WAVES = shader.MAX_WAVES
SHADOW_BASE = MAX_WAVES
OVERFLOW = 2 * MAX_WAVES
STATE = 2 * MAX_WAVES + 2  # words before the pixels' sums: ray counts, shadow counts, overflow, wave
WAVES_BYTES = 32
PIXEL_WORDS = 6  # a pixel's sums: three channels of two words
# The three storage buffers of a band's queues (bands.Buffer): the floats (both
# ray queues, the hits' t and half-chord, the shadow queue), the ints (both ray
# queues, the hits' spheres, the shadow queue), the state and the band's sums.
QUEUES = [
    bands.Buffer(ray=4 * (2 * stages.RAY_ROWS + 2), shadow=4 * stages.SHADOW_ROWS),
    bands.Buffer(ray=4 * (2 * stages.RAY_IDS + 1), shadow=4 * stages.SHADOW_IDS),
    bands.Buffer(fixed=4 * STATE, pixel=4 * PIXEL_WORDS),
]
ENTRIES = ("main_wf_start", "main_wf_primary", "main_wf_extend", "main_wf_shade", "main_wf_shadow",
           "main_wf_advance", "main_wf_finish")  # fmt: skip


class Wavefront(bands.Queues):
    """The wavefront's pipelines, queues and sums for one Compute (its
    device, spheres, tree, shading, texture and hits)."""

    shadow_base, overflow = SHADOW_BASE, OVERFLOW  # the columns of a band's state

    def __init__(self, compute, depth: int):
        import wgpu

        self.compute, self.depth = compute, depth
        device = compute.device
        self.device = device
        pixels = compute.width * compute.height
        self.pixels = pixels
        self.waves = device.create_buffer(size=WAVES_BYTES, usage=wgpu.BufferUsage.UNIFORM | wgpu.BufferUsage.COPY_DST)
        self.pipelines = None
        self.bind_group = None
        self.retraced = 0
        self._allocate(self._plan(compute.height, pixels * RAYS_A_PIXEL, pixels * SHADOWS_A_PIXEL))

    def _plan(self, rows: int, rays: int, shadows: int) -> bands.Plan:
        """Queues for rays and shadows slots that `rows` rows need (bands.plan),
        each buffer within the device's largest storage buffer."""
        limits = self.device.limits
        device = min(limits["max-storage-buffer-binding-size"], limits["max-buffer-size"])
        limit = bands.capped(device)
        holds = (
            f"this device's largest buffer ({device / 2**20:.0f} MiB)"
            if limit == device
            else f"the queues' limit ({limit / 2**20:.1f} MiB)"
        )
        return bands.plan(self.compute.width, rows, rays, shadows, QUEUES, limit, GROUP, holds)

    def _allocate(self, plan: bands.Plan) -> None:
        """The queues and sums of `plan`, and each band's sizes (a Waves a band)."""
        import wgpu

        self.plan = plan
        rays, shadows = plan.rays, plan.shadows
        self.ray_capacity, self.shadow_capacity = rays, shadows
        band_pixels = plan.rows * self.compute.width
        floats, ints, sums = (b.bytes(rays, shadows, band_pixels) for b in QUEUES)
        storage = wgpu.BufferUsage.STORAGE
        self.floats = self.ints = self.sums = None  # the old ones go first
        self.floats = self.device.create_buffer(size=floats, usage=storage)
        self.ints = self.device.create_buffer(size=ints, usage=storage)
        # zeroed at creation; each band's last dispatch zeroes what it read
        self.sums = self.device.create_buffer(size=sums, usage=storage | wgpu.BufferUsage.COPY_SRC)
        rows = plan.bands(0, self.compute.height)
        sizes = np.zeros((len(rows), WAVES_BYTES // 4), np.uint32)
        for band, (first, end) in enumerate(rows):
            pixels = (end - first) * self.compute.width
            sizes[band, :5] = rays, shadows, pixels, first * self.compute.width, _groups(pixels)
            sizes[band, 5] = band
        self.sizes = self.device.create_buffer_with_data(data=sizes.tobytes(), usage=wgpu.BufferUsage.COPY_SRC)
        self.state_read = self.device.create_buffer(
            size=len(rows) * STATE * 4, usage=wgpu.BufferUsage.COPY_DST | wgpu.BufferUsage.MAP_READ
        )
        self.bands = rows
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
        code = shader.source(compute.workgroup, compute.accel, "wavefront", compute.primitive)
        module = self.device.create_shader_module(code=code)
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

    def encode(self, encoder, timestamp_writes=None) -> None:
        """A frame's compute passes into encoder (the frame uniform already
        written), a pass a band, each followed by the copy of its state words
        for overflowed(). timestamp_writes: the Compute's, written at the
        first pass's beginning and the last one's end."""
        self.compile()
        if self.bind_group is None or self._bound_tree is not self.compute.tree:
            self._bind()
        last = len(self.bands) - 1
        for band, (first, end) in enumerate(self.bands):
            encoder.copy_buffer_to_buffer(self.sizes, band * WAVES_BYTES, self.waves, 0, WAVES_BYTES)
            writes = None
            if timestamp_writes is not None:  # the first pass's beginning, the last one's end
                begin, finish = "beginning_of_pass_write_index", "end_of_pass_write_index"
                ends = {begin: timestamp_writes[begin]} if band == 0 else {}
                ends |= {finish: timestamp_writes[finish]} if band == last else {}
                writes = {"query_set": timestamp_writes["query_set"], **ends} if ends else None
            compute_pass = encoder.begin_compute_pass(timestamp_writes=writes)
            self._encode_band(compute_pass, _groups((end - first) * self.compute.width))
            compute_pass.end()
            encoder.copy_buffer_to_buffer(self.sums, 0, self.state_read, band * STATE * 4, STATE * 4)

    def _encode_band(self, compute_pass, groups: int) -> None:
        """A band's dispatches (its sizes in the uniform)."""
        compute_pass.set_bind_group(0, self.bind_group)

        def run(entry: str, count: int) -> None:
            compute_pass.set_pipeline(self.pipelines[entry])
            compute_pass.dispatch_workgroups(count, 1, 1)

        run("main_wf_start", 1)
        run("main_wf_primary", groups)
        for _ in range(self.depth + 1):
            run("main_wf_extend", groups)
            run("main_wf_shade", groups)
            run("main_wf_shadow", groups)
            run("main_wf_advance", 1)
        run("main_wf_finish", groups)

    def _read_counts(self) -> np.ndarray:
        """The last frame's bands' states, their queue counts (bands.Queues.overflowed), waiting for it."""
        import wgpu

        self.state_read.map_sync(wgpu.MapMode.READ)
        try:
            return np.frombuffer(self.state_read.read_mapped(), np.uint32).reshape(-1, STATE).copy()
        finally:
            self.state_read.unmap()


def _groups(pixels: int) -> int:
    """Workgroups a band's stages are dispatched on."""
    return min(GROUPS, max(1, -(-pixels // GROUP)))
