"""The real-time viewer: the thesis's window, a sink for traced frames.

    scene -> camera -> backend tracer (worker thread) -> Frame -> texture -> full-screen quad -> window

Pure logic, testable without a window:
    bindings.py   keys -> actions, and the help text
    controls.py   keys held and mouse drags -> camera motion
    spheres.py    +/- and the ramp (test 7): which prefix of which scene is traced
    shading.py    the shading toggle and the light keys: what the next frame is lit by
    pacing.py     the handoff between tracer thread and window; frame time and fps
    overlay.py    the title bar's status line
    state.py      the event handler, and what to trace next
    worker.py     the thread that calls the backends' tracers
The window (wgpu, rendercanvas with glfw):
    gpu.py        the texture-to-quad pipeline, formats, reading back what was drawn
    window.py     the canvas, its events and draws

Nothing heavy is imported here, so `raybench --help` stays quick.
"""

from __future__ import annotations

from pathlib import Path


def view(state, size: tuple[int, int], *, frames: int | None = None, screenshot: Path | None = None):
    """Open the window on state (a viewer.state.ViewerState: the scene, its
    device and options, the first frame's shading, whether the spheres move)
    and run until it closes; returns the window (what it saved, and its state
    with the last frame shown)."""
    from .window import ViewerWindow

    window = ViewerWindow(state, size, frames=frames, screenshot=screenshot)
    window.run()
    return window
