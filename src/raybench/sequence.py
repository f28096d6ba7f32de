"""A frame sequence's folder: one PNG a frame (frame_00000.png on) and a
marker, .raybench-sequence.json, that says which sequence they are of.

A sequence resumes where it stopped: the frames on disk are kept and only
the missing ones are traced. So that it never mixes two sequences, the
folder is checked before anything is traced (prepare):

- each frame there must be a regular file holding a PNG header of this
  run's size; anything else where a frame belongs (a folder, a symlink, a
  FIFO, a file that is not a PNG, a frame of another size) is one line
  naming it, and nothing is traced;
- the marker names the sequence by what decides its pixels: the size, the
  number of frames, the shading, and digests (SHA-256) of the scene's arrays
  and of the cameras. Frames under a marker of another sequence are refused
  in one line; a folder of frames without a marker (an older raybench's) is
  taken where their size is right, and marked.

The device and the PNG level are left out: they change no pixel.
"""

from __future__ import annotations

import contextlib
import hashlib
import json
import os
import stat
import threading
from pathlib import Path

import numpy as np

from .errors import RaybenchError
from .files import file_kind, lstat_or_none, output_mode, read_json, unix_flags, write_atomic

MARKER = ".raybench-sequence.json"
FORMAT = "raybench-sequence"
VERSION = 1
# Enough of a PNG file to read its header (signature and IHDR chunk).
PNG_HEADER = 33


def frame_path(out_dir, number: int) -> Path:
    return Path(out_dir) / f"frame_{number:05d}.png"


def identity(scene, cameras, width: int, height: int, shading="thesis", depth=None, shadow_samples=None) -> dict:
    """What names a sequence in its marker: every input that decides a frame's pixels."""
    from .lighting import Shading

    # what is traced: the spheres (the bytes every earlier marker hashed), or a mesh scene's triangles
    digest = hashlib.sha256(np.ascontiguousarray(scene.traced().buffer()).tobytes())
    if isinstance(shading, Shading) or shading == "whitted":
        made = shading if isinstance(shading, Shading) else Shading.of(scene, depth, shadow_samples)
        for array in (made.materials, made.lights, made.pattern, made.params):
            digest.update(np.ascontiguousarray(array).tobytes())
        shading = f"whitted, depth {made.depth}, {made.shadow_samples} shadow samples"
    views = hashlib.sha256(json.dumps([c.to_dict() for c in cameras]).encode())
    return {
        "format": FORMAT,
        "version": VERSION,
        "size": [int(width), int(height)],
        "frames": len(cameras),
        "shading": str(shading),
        "scene": digest.hexdigest(),
        "cameras": views.hexdigest(),
    }


# What each field of the marker is called in a message.
_SAID = {"size": "size", "frames": "number of frames", "shading": "shading", "scene": "scene",
         "cameras": "camera path"}  # fmt: skip


def prepare(out_dir, marker: dict, option: str = "") -> list[int]:
    """The numbers of the frames still to trace in out_dir for the sequence
    that `marker` (identity()) names, after the checks above; the marker is
    written (atomically) before they are traced. One line, nothing traced,
    where the folder holds anything a frame of this sequence could not be."""
    out_dir = Path(out_dir)
    where = f"{option} {out_dir}" if option else str(out_dir)
    width, height = marker["size"]
    todo, kept = [], 0
    for n in range(marker["frames"]):
        path = frame_path(out_dir, n)
        if _frame_there(path, where, width, height):
            kept += 1
        else:
            todo.append(n)
    mark = out_dir / MARKER
    output_mode(mark, option)  # a marker that is not a regular file is refused, as any output
    old, damaged = None, None
    if os.path.lexists(mark):
        try:
            old = read_json(mark, "sequence marker")
        except RaybenchError as exc:
            damaged = str(exc).split(": ", 1)[-1]
    if kept and damaged is not None:
        raise RaybenchError(
            f"{where}: its sequence marker {MARKER} is damaged ({damaged}), so its {kept} frames cannot be told "
            "to be this sequence's; remove the marker if they are, or the frames if not"
        )
    if kept and old is not None and old != marker:
        differ = [_SAID[k] for k in _SAID if not isinstance(old, dict) or old.get(k) != marker.get(k)]
        raise RaybenchError(
            f"{where}: holds {kept} frames of another sequence (its {', '.join(differ)} differ from this run's); "
            "give another folder, or remove its frames to trace this sequence there"
        )
    if old != marker:  # none, or one of no frames here: this sequence's from now on
        write_atomic(mark, (json.dumps(marker, indent=1) + "\n").encode(), option)
    return todo


def _frame_there(path: Path, where: str, width: int, height: int) -> bool:
    """Whether frame `path` is there, checked to be one of this run's
    size; False where nothing is."""
    info = lstat_or_none(path, lambda why: f"{where}: cannot look at {path.name} ({why})")
    if info is None:
        return False
    fix = "remove it, and the frame is traced again"
    if not stat.S_ISREG(info.st_mode):
        kind = "symlink" if stat.S_ISLNK(info.st_mode) else file_kind(info.st_mode)
        raise RaybenchError(f"{where}: {path.name} is a {kind}, not a frame; {fix}")
    size = png_size(path)
    if size is None:
        raise RaybenchError(f"{where}: {path.name} is not a PNG image; {fix}")
    if size != (width, height):
        raise RaybenchError(
            f"{where}: {path.name} is {size[0]}x{size[1]}, this sequence's frames {width}x{height}: the folder "
            "holds another sequence; give another folder, or remove its frames"
        )
    return True


def png_size(path) -> tuple[int, int] | None:
    """(width, height) from a PNG file's header, read without decoding (nor
    Pillow's guard against large images); None where the file is not a PNG."""
    try:
        with open(path, "rb", opener=lambda p, flags: os.open(p, flags | unix_flags("O_NOFOLLOW", "O_NONBLOCK"))) as f:
            head = f.read(PNG_HEADER)
    except OSError:
        return None
    if len(head) < PNG_HEADER or head[:8] != b"\x89PNG\r\n\x1a\n" or head[12:16] != b"IHDR":
        return None
    return int.from_bytes(head[16:20], "big"), int.from_bytes(head[20:24], "big")


_pillow_limit = threading.Lock()


@contextlib.contextmanager
def trusted_pixels(pixels: int):
    """Pillow's guard against decompression bombs (a warning past
    Image.MAX_IMAGE_PIXELS, an error past twice that) raised, for the block,
    to images of `pixels` pixels: raybench's own frames, of a size it was
    asked for and checked (prepare), are no bomb. Any larger image, and every
    image outside the block, meets Pillow's own limit."""
    from PIL import Image

    with _pillow_limit:
        default = Image.MAX_IMAGE_PIXELS
        if default is not None:
            Image.MAX_IMAGE_PIXELS = max(default, int(pixels))
        try:
            yield
        finally:
            Image.MAX_IMAGE_PIXELS = default
