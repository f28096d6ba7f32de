"""A frame sequence's PNGs as one animated GIF, through Pillow: what
`raybench render --path ... --gif FILE` writes once the sequence is whole.

Each frame gets its own 256-colour palette (Pillow's adaptive one), so the GIF
is an approximation of the PNGs, which stay the exact frames. Pillow holds
every frame, palettised (1 byte a pixel), until the file is written: 240
frames at 1680x1050 are some 420 MB.
"""

from __future__ import annotations

import io
from collections.abc import Iterable
from pathlib import Path

from .errors import RaybenchError
from .files import write_atomic

# Frames a second. A GIF's delays are in hundredths of a second: 25 a second
# (40 ms) is kept exactly, where 30 (33.3 ms) is not.
FPS = 25


def check_path(path) -> Path:
    path = Path(path)
    if path.suffix.lower() != ".gif":
        raise RaybenchError(f"--gif {path}: the output must be a .gif file")
    if not path.parent.is_dir():
        raise RaybenchError(f"--gif {path}: folder {path.parent} does not exist")
    return path


def write_gif(frames: Iterable, path, fps: int = FPS) -> None:
    """The PNG files frames, in order, as an animated GIF at path (written
    atomically), looping forever, fps frames a second."""
    from PIL import Image

    path = check_path(path)
    if isinstance(fps, bool) or not isinstance(fps, int) or not 1 <= fps <= 100:
        raise RaybenchError(f"fps: must be a whole number 1 to 100, got {fps!r}")
    images = (Image.open(frame).convert("RGB") for frame in frames)
    first = next(images, None)
    if first is None:
        raise RaybenchError(f"--gif {path}: no frames to write")
    buf = io.BytesIO()
    first.save(buf, format="GIF", save_all=True, append_images=images, duration=round(1000 / fps), loop=0)
    write_atomic(path, buf.getvalue())
