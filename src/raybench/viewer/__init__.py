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


def view(
    scene,
    *,
    device: str,
    seed: int | None,
    size: tuple[int, int],
    options: dict | None = None,
    frames: int | None = None,
    screenshot: Path | None = None,
    shading: str = "thesis",
    depth: int | None = None,
    shadow_samples: int | None = None,
    animate: bool = False,
):
    """Open the window on scene and run until it closes; returns the window
    (what it saved, and its state with the last frame shown). shading, depth
    and shadow_samples: the first frame's, as render() takes them; animate:
    the spheres move every frame (viewer.moving)."""
    from .state import ViewerState
    from .window import ViewerWindow

    state = ViewerState(
        scene,
        device=device,
        seed=seed,
        options=options,
        shading=shading,
        depth=depth,
        shadow_samples=shadow_samples,
        animate=animate,
    )
    window = ViewerWindow(state, size, frames=frames, screenshot=screenshot)
    window.run()
    return window
