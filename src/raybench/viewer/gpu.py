"""The thesis's texture-to-quad pipeline, in wgpu.

    traced frame (bytes) -> TEXTURE -> VERTEX SHADER (a full-screen quad) -> PIXEL SHADER -> target

Colours must reach the screen as the very bytes `raybench render` writes to a
PNG. Two choices make that exact:

- the frame texture is rgba8unorm, not rgba8unorm-srgb: reading it gives
  byte / 255 with no sRGB decoding;
- the target is written through a non-sRGB view: a non-sRGB surface format
  (bgra8unorm or rgba8unorm) when the surface offers one, else the sRGB format
  configured with its non-sRGB twin as view format. Writing through a non-sRGB
  view stores round(value * 255) = the byte that was read, where an sRGB view
  would encode it (a byte of 128 would land as 188). The picture is then shown
  as the same bytes a PNG viewer shows.

The pixel shader reads texels with textureLoad (nearest texel, no filtering):
at equal sizes every fragment copies exactly one texel; a frame of another size
(traced before a resize) is stretched to fill the window until the next one.
"""

from __future__ import annotations

import sys
from dataclasses import dataclass

import numpy as np

from ..backends.wgpu.adapters import native_stderr_captured
from ..errors import RaybenchError

FRAME_FORMAT = "rgba8unorm"
SUGGEST = "use `raybench render` to write frames as PNG files"  # ends every "cannot show a window" error

QUAD_SHADER = """
struct Varyings {
    @builtin(position) position: vec4<f32>,
    @location(0) uv: vec2<f32>,
};

// One triangle that covers the target: the full-screen quad, clipped.
@vertex
fn vs_main(@builtin(vertex_index) index: u32) -> Varyings {
    var corners = array<vec2<f32>, 3>(vec2<f32>(-1.0, -1.0), vec2<f32>(3.0, -1.0), vec2<f32>(-1.0, 3.0));
    let p = corners[index];
    var out: Varyings;
    out.position = vec4<f32>(p, 0.0, 1.0);
    out.uv = vec2<f32>(0.5 * p.x + 0.5, 0.5 - 0.5 * p.y);  // row 0 of the frame at the top
    return out;
}

@group(0) @binding(0) var frame: texture_2d<f32>;

@fragment
fn fs_main(in: Varyings) -> @location(0) vec4<f32> {
    let size = vec2<i32>(textureDimensions(frame));
    let texel = clamp(vec2<i32>(floor(in.uv * vec2<f32>(size))), vec2<i32>(0, 0), size - vec2<i32>(1, 1));
    return textureLoad(frame, texel, 0);
}
"""

_NON_SRGB = ("bgra8unorm", "rgba8unorm")


@dataclass(frozen=True)
class TargetFormat:
    """configure: the surface's format; view: the one the quad is drawn through."""

    configure: str
    view: str

    @property
    def view_formats(self) -> list[str]:
        return [self.view] if self.view != self.configure else []


def choose_target_format(formats) -> TargetFormat:
    """From the formats a surface offers: a non-sRGB 8-bit format if any, else an
    sRGB one drawn through its non-sRGB view (see the module's docstring)."""
    formats = list(formats)
    for fmt in formats:
        if fmt in _NON_SRGB:
            return TargetFormat(fmt, fmt)
    for fmt in formats:
        if fmt.endswith("-srgb") and fmt[: -len("-srgb")] in _NON_SRGB:
            return TargetFormat(fmt, fmt[: -len("-srgb")])
    raise RaybenchError(
        f"the window's surface offers no 8-bit RGBA or BGRA format (it offers {', '.join(formats)}); {SUGGEST}"
    )


def pixels_to_rgb(data, width: int, height: int, fmt: str) -> np.ndarray:
    """Bytes read back from a texture of format fmt -> (H, W, 3) uint8 RGB."""
    pixels = np.frombuffer(data, dtype=np.uint8).reshape(height, width, 4)
    if fmt.startswith("bgra"):
        return np.ascontiguousarray(pixels[..., 2::-1])
    return np.ascontiguousarray(pixels[..., :3])


class TextureQuad:
    """The frame texture and the pipeline that draws it on a full-screen quad."""

    def __init__(self, device, target_format: str):
        import wgpu

        self.wgpu = wgpu
        self.device = device
        self.target_format = target_format
        shader = device.create_shader_module(code=QUAD_SHADER)
        self.layout = device.create_bind_group_layout(
            entries=[
                {
                    "binding": 0,
                    "visibility": wgpu.ShaderStage.FRAGMENT,
                    "texture": {"sample_type": wgpu.TextureSampleType.float, "view_dimension": "2d"},
                }
            ]
        )
        self.pipeline = device.create_render_pipeline(
            layout=device.create_pipeline_layout(bind_group_layouts=[self.layout]),
            vertex={"module": shader, "entry_point": "vs_main", "buffers": []},
            primitive={"topology": wgpu.PrimitiveTopology.triangle_list},
            depth_stencil=None,
            multisample=None,
            fragment={"module": shader, "entry_point": "fs_main", "targets": [{"format": target_format}]},
        )
        self.texture = None  # the texture drawn: the uploaded one, or the compute pass's (wgpu)
        self.bind_group = None
        self._uploaded = None  # the texture upload() writes, kept across frames of one size

    @property
    def frame_size(self) -> tuple[int, int] | None:
        return None if self.texture is None else self.texture.size[:2]

    def show(self, texture) -> None:
        """Draw this texture from now on (the wgpu backend's frame texture: no copy)."""
        if texture is not self.texture:
            self.texture = texture
            self.bind_group = self.device.create_bind_group(
                layout=self.layout, entries=[{"binding": 0, "resource": texture.create_view()}]
            )

    def upload(self, rgba: np.ndarray) -> None:
        """Copy an (H, W, 4) uint8 frame into the texture (made anew when the size changes)."""
        height, width = rgba.shape[:2]
        if self._uploaded is None or self._uploaded.size[:2] != (width, height):
            usage = self.wgpu.TextureUsage.TEXTURE_BINDING | self.wgpu.TextureUsage.COPY_DST
            self._uploaded = self.device.create_texture(size=(width, height, 1), format=FRAME_FORMAT, usage=usage)
        self.device.queue.write_texture(
            {"texture": self._uploaded},
            np.ascontiguousarray(rgba),
            {"bytes_per_row": width * 4, "rows_per_image": height},
            (width, height, 1),
        )
        self.show(self._uploaded)

    def encode(self, encoder, target_view) -> None:
        """Record the draw of the frame over the whole target (before the first
        frame, a clear to black) into encoder."""
        render_pass = encoder.begin_render_pass(
            color_attachments=[
                {
                    "view": target_view,
                    "resolve_target": None,
                    "clear_value": (0, 0, 0, 1),
                    "load_op": self.wgpu.LoadOp.clear,
                    "store_op": self.wgpu.StoreOp.store,
                }
            ]
        )
        if self.texture is not None:
            render_pass.set_pipeline(self.pipeline)
            render_pass.set_bind_group(0, self.bind_group)
            render_pass.draw(3, 1, 0, 0)
        render_pass.end()

    def draw(self, target_view) -> None:
        """Draw the frame over the whole target, in a command buffer of its own."""
        encoder = self.device.create_command_encoder()
        self.encode(encoder, target_view)
        self.device.queue.submit([encoder.finish()])

    def read(self, texture) -> np.ndarray:
        """What a texture holds (the window's, after draw(); or an offscreen one), as (H, W, 3) RGB."""
        width, height = texture.size[:2]
        data = self.device.queue.read_texture(
            {"texture": texture, "origin": (0, 0, 0), "mip_level": 0},
            {"offset": 0, "bytes_per_row": width * 4, "rows_per_image": height},
            (width, height, 1),
        )
        return pixels_to_rgb(data, width, height, texture.format)

    def draw_offscreen(self, width: int, height: int) -> np.ndarray:
        """The same pipeline drawn into an offscreen texture of the target's
        format and the given size, read back: the screenshot where a surface
        cannot be read (no COPY_SRC), and the window-free test of this path."""
        usage = self.wgpu.TextureUsage.RENDER_ATTACHMENT | self.wgpu.TextureUsage.COPY_SRC
        target = self.device.create_texture(size=(width, height, 1), format=self.target_format, usage=usage)
        self.draw(target.create_view())
        return self.read(target)


def request_device(canvas=None, adapter: str | None = None):
    """A wgpu adapter (one that can draw to canvas, if given; the one named by
    adapter, if given) and its device, with the limits and timestamp queries
    the wgpu tracer can use; a RaybenchError that says so, in one line, when
    there is none.

    The drivers' own output while they are probed is passed on when an adapter
    is found, and dropped when none is: then wgpu's reason, in the error, says
    what each backend lacked, and the error stays the only line."""
    from ..backends.wgpu import adapters

    if adapter is not None:
        chosen = adapters.choose(adapter)  # a name that matches none: its own one-line error
        return chosen.adapter, adapters.request_device(chosen)
    failure = None
    with native_stderr_captured() as native:
        try:
            import wgpu

            found = wgpu.gpu.request_adapter_sync(power_preference="high-performance", canvas=canvas)
            device = found.request_device_sync(**adapters.device_requirements(found))
        except Exception as exc:  # noqa: BLE001 - wgpu reports "no adapter" as RuntimeError, ImportError, ...
            failure = exc
    if failure is not None:
        reason = " ".join(str(failure).split()) or type(failure).__name__
        raise RaybenchError(
            f"no usable graphics adapter: wgpu found none that can draw to a window ({reason}); {SUGGEST}"
        )
    sys.stderr.write(native["text"])
    return found, device
