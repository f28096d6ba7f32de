"""A frame sequence's PNGs as one animated GIF, through Pillow: what
`raybench render --path ... --gif FILE` writes once the sequence is whole.

Each frame gets its own 256-colour palette (Pillow's adaptive one), so the GIF
is an approximation of the PNGs, which stay the exact frames. Pillow holds
every frame, palettised (1 byte a pixel), until the file is written, and the
file itself is made in memory: up to about BYTES_PER_PIXEL bytes a pixel of
every frame (240 frames at 1680x1050 are some 1.7 GB), checked before the
sequence is traced.
"""

from __future__ import annotations

import io
import os
from collections.abc import Iterable
from pathlib import Path

from .errors import RaybenchError, one_line
from .files import write_atomic

# Frames a second. A GIF's delays are in hundredths of a second: 25 a second
# (40 ms) is kept exactly, where 30 (33.3 ms) is not.
FPS = 25
# A GIF's width and height are 16-bit fields.
MAX_SIDE = 65535
# Memory while a GIF is made, in bytes a pixel of a frame: each frame
# Pillow holds palettised, with its part of the file made in memory
# (BYTES_PER_PIXEL), and once the frame being read and quantised (RGB,
# copies; WORKING_BYTES_PER_PIXEL), as measured (the README's sequences).
BYTES_PER_PIXEL = 4
WORKING_BYTES_PER_PIXEL = 16


def check_path(path) -> Path:
    path = Path(path)
    if path.suffix.lower() != ".gif":
        raise RaybenchError(f"--gif {path}: the output must be a .gif file")
    if not os.path.isdir(path.parent):
        raise RaybenchError(f"--gif {path}: folder {path.parent} does not exist")
    return path


def check_fits(frames: int, width: int, height: int) -> None:
    """Refuse a GIF that could not be made: a side over MAX_SIDE, or more
    memory than this process may still take."""
    from .host import host_available_bytes

    if width > MAX_SIDE or height > MAX_SIDE:
        raise RaybenchError(f"--gif: a GIF is at most {MAX_SIDE} pixels a side, the frames are {width}x{height}")
    need = width * height * (frames * BYTES_PER_PIXEL + WORKING_BYTES_PER_PIXEL)
    available = host_available_bytes()
    if need > available:
        raise RaybenchError(
            f"--gif: {frames} frames of {width}x{height} need about {need / 2**30:.2f} GiB while the GIF is made, "
            f"more than the {available / 2**30:.2f} GiB available; fewer frames or a smaller --size"
        )


def write_gif(frames: Iterable, path, fps: int = FPS, size: tuple[int, int] | None = None) -> None:
    """The PNG files frames, in order, as an animated GIF at path (written
    atomically), looping forever, fps frames a second.

    size: the frames' (width, height), where they are raybench's own (a
    sequence's, checked by raybench.sequence.prepare): each must be that
    size, and Pillow's guard against decompression bombs is raised to it
    (sequence.trusted_pixels), so that large frames are read. Without it,
    Pillow's own limit holds (about 89 M pixels warned of, 179 M refused)."""
    from PIL import Image

    from .sequence import trusted_pixels

    path = check_path(path)
    if isinstance(fps, bool) or not isinstance(fps, int) or not 1 <= fps <= 100:
        raise RaybenchError(f"fps: must be a whole number 1 to 100, got {fps!r}")
    frames = [Path(frame) for frame in frames]
    if not frames:
        raise RaybenchError(f"--gif {path}: no frames to write")

    def read(frame: Path):
        try:
            with Image.open(frame) as image:
                if size is not None and image.size != tuple(size):
                    raise RaybenchError(
                        f"--gif {path}: frame {frame} is {image.size[0]}x{image.size[1]}, not {size[0]}x{size[1]}"
                    )
                return image.convert("RGB")
        except RaybenchError:
            raise
        except (OSError, ValueError, SyntaxError, Image.DecompressionBombError) as exc:
            raise RaybenchError(f"--gif {path}: cannot read frame {frame} ({one_line(exc)})") from None

    buf = io.BytesIO()
    with trusted_pixels(size[0] * size[1] if size is not None else 0):
        first = read(frames[0])
        check_fits(len(frames), *first.size)
        images = (read(frame) for frame in frames[1:])
        first.save(buf, format="GIF", save_all=True, append_images=images, duration=round(1000 / fps), loop=0)
    write_atomic(path, buf.getvalue(), "--gif")
