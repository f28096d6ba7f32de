"""The status line shown in the window's title bar.

The title bar, not text drawn over the picture: what the window shows stays
exactly the traced frame, byte for byte what `raybench render` writes, and a
screenshot is the picture alone.
"""

from __future__ import annotations

from typing import NamedTuple

from .bindings import help_summary

SEPARATOR = "  |  "


def _ms(ms: float | None) -> str:
    if ms is None:
        return "- ms"
    return f"{ms:.1f} ms" if ms < 1000 else f"{ms / 1000:.2f} s"


def _fps(fps: float | None) -> str:
    if fps is None:
        return "- fps"
    return f"{fps:.1f} fps" if fps < 100 else f"{fps:.0f} fps"


def _rays(per_s: float | None) -> str:
    if per_s is None:
        return "- rays/s"
    for scale, prefix in ((1e9, "G"), (1e6, "M"), (1e3, "k")):
        if per_s >= scale:
            return f"{per_s / scale:.3g} {prefix} rays/s"
    return f"{per_s:.0f} rays/s"


class Status(NamedTuple):
    """What the status line says of what is on screen: device, sphere count,
    resolution, frame time and frames per second; update: with --animate, the
    last frame's tree update (its kind, "refit" or "build", and ms); shading
    and rays_per_s: with a shading, it and the rays cast per second (under
    Whitted's, every kind counted); ramp: the ramp flag; message: the latest."""

    device: str
    spheres: int
    width: int
    height: int
    frame_ms: float | None
    fps: float | None
    ramp: bool = False
    message: str | None = None
    shading: str | None = None
    rays_per_s: float | None = None
    update: tuple[str, float] | None = None
    noun: str = "spheres"  # what the count counts: a mesh scene's "triangles"


def status_line(status: Status) -> str:
    """The status: its device, sphere count, resolution; the update before
    the trace; the frame time and fps; the shading and its rays per second;
    then the ramp flag and the latest message."""
    device, spheres, width, height, frame_ms, fps, ramp, message, shading, rays_per_s, update, noun = status
    parts = ["raybench", device, f"{spheres:,} {noun}", f"{width}x{height}"]
    if update is not None:
        # a refit takes a fraction of a ms: two decimals there
        parts.append(f"{update[0]} {update[1]:.2f} ms" if update[1] < 10 else f"{update[0]} {_ms(update[1])}")
    parts += [f"{'trace' if update is not None else 'frame'} {_ms(frame_ms)}", _fps(fps)]
    if shading is not None:
        parts += [shading, _rays(rays_per_s)]
    if ramp:
        parts.append("ramp")
    if message:
        parts.append(message)
    return SEPARATOR.join(parts)


def waiting_line(
    *, device: str, spheres: int, width: int, height: int, message: str | None = None, noun: str = "spheres"
) -> str:
    """Before the first frame is on screen (the first frame compiles the kernel)."""
    parts = [
        "raybench",
        device,
        f"{spheres:,} {noun}",
        f"{width}x{height}",
        "tracing the first frame (compiling the kernel)...",
    ]
    if message:
        parts.append(message)
    return SEPARATOR.join(parts)


def help_line() -> str:
    return "raybench keys: " + help_summary()
