"""The frame's RGB bytes packed on the GPU for the host (pack.wgsl).

The trace pass writes an RGBA texture, which the viewer draws as it is.
trace() needs (H, W, 3) bytes on the host: picking RGB out of RGBA rows there
took several times as long as the straight copy out of the mapped buffer
(docs/notes/wgpu.md#the-wgpu-frames-readback). Packed on the GPU,
the readback is one straight copy of the frame's own bytes.
"""

from __future__ import annotations

import numpy as np

from .shader import _piece

WORKGROUP = 64  # pack.wgsl's @workgroup_size
MAX_GROUPS = 65535  # WebGPU's maxComputeWorkgroupsPerDimension, its default


def packed_bytes(width: int, height: int) -> int:
    """The packed buffer's size: whole groups of four pixels, 12 bytes each."""
    return -(-width * height // 4) * 12


def dispatch(width: int, height: int) -> tuple[int, int]:
    """Workgroups (x, y) for a quad an invocation: in y as well once x is full."""
    quads = -(-width * height // 4)
    groups = -(-quads // WORKGROUP)
    return (groups, 1) if groups <= MAX_GROUPS else (MAX_GROUPS, -(-groups // MAX_GROUPS))


class Packer:
    """Encodes the pass that packs `texture` (rgba8unorm, TEXTURE_BINDING) into `packed`."""

    def __init__(self, device, texture, width: int, height: int):
        import wgpu

        self.packed = device.create_buffer(
            size=packed_bytes(width, height), usage=wgpu.BufferUsage.STORAGE | wgpu.BufferUsage.COPY_SRC
        )
        size = device.create_buffer_with_data(
            data=np.array([width, height, 0, 0], np.uint32).tobytes(), usage=wgpu.BufferUsage.UNIFORM
        )
        module = device.create_shader_module(code=_piece("pack.wgsl"))
        self.pipeline = device.create_compute_pipeline(layout="auto", compute={"module": module, "entry_point": "pack"})
        self.bind_group = device.create_bind_group(
            layout=self.pipeline.get_bind_group_layout(0),
            entries=[
                {"binding": 0, "resource": texture.create_view()},
                {"binding": 1, "resource": {"buffer": self.packed}},
                {"binding": 2, "resource": {"buffer": size}},
            ],
        )
        self.groups = dispatch(width, height)

    def encode(self, encoder) -> None:
        compute_pass = encoder.begin_compute_pass()
        compute_pass.set_pipeline(self.pipeline)
        compute_pass.set_bind_group(0, self.bind_group)
        compute_pass.dispatch_workgroups(*self.groups, 1)
        compute_pass.end()
