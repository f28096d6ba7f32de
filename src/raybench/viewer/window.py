"""The window: a rendercanvas glfw canvas drawn with wgpu (Vulkan, Metal or D3D12).

It glues the parts together and decides nothing itself: events go to
ViewerState.handle_event, frames are traced by the TraceWorker's thread, each
finished frame is uploaded to the texture and drawn by TextureQuad, and the
title bar shows ViewerState.title(). What a draw does to a frame is
drawing.FrameDrawer's, given the surface's texture: this module adds the
canvas (its surface, events, title and the loop that schedules draws).

wgpu frames take another road, the thesis's: no copy. The draw records the
compute pass, which writes the frame texture, and the quad's render pass,
which draws that texture, into one command buffer on the window's own device
(zero_copy.py), and submits it; the worker thread only waits for the GPU to
finish (and reads its timestamps), then hands the frame over like any other:
the next draw counts it, shows the same texture again and asks for the next
frame. The loop never waits for the GPU.

Pacing: the canvas draws on demand. The worker asks for a draw (through the
loop's call_soon_threadsafe) when a frame is ready; that draw shows it and
hands the worker the next request, so the device traces frame k + 1 while
frame k is on screen. A slow device never blocks the loop: events, resizes
and redraws of the frame on screen go on while it traces; a redraw at least
MIN_FPS times a second keeps the title's numbers and messages current.
"""

from __future__ import annotations

import ctypes
import ctypes.util
import datetime
import os
import re
import sys
import warnings
from pathlib import Path

import numpy as np

from ..errors import RaybenchError, one_line
from ..files import write_atomic
from ..render import png_bytes
from .bindings import help_lines
from .drawing import FrameDrawer, wgpu_tracer_here
from .gpu import SUGGEST, TextureQuad, choose_target_format, request_device
from .state import ViewerState

MIN_FPS = 2  # redraws per second at least: the title's frame time, fps and messages stay current
MAX_FPS = 240  # draws per second at most; frame times are measured by the tracer, not by this cap


def check_display() -> None:
    """Refuse, in one line, to open a window where there is no screen."""
    if sys.platform.startswith("linux") and not (os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY")):
        raise RaybenchError(
            f"no display: DISPLAY and WAYLAND_DISPLAY are not set, so there is no screen for the window; {SUGGEST}"
        )
    try:
        import glfw
    except Exception as exc:  # noqa: BLE001 - ImportError, or OSError from loading libglfw
        raise RaybenchError(f"no display: the glfw library cannot be loaded ({exc}); {SUGGEST}") from None
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        ok = glfw.init()
    if not ok:
        reason = "; ".join(_glfw_message(w.message) for w in caught) or "glfw.init() failed"
        raise RaybenchError(f"no display: cannot open a window ({reason}); {SUGGEST}")
    _one_line_on_lost_display()


# Xlib's own answer to losing the X server under an open window (the server
# killed, the connection cut) is two lines of its own and exit(1), from inside
# whatever Xlib call notices. This handler says it in raybench's one line and
# exits 2 instead. It must not return: Xlib exits when it does. Nothing is
# left half-written: every output is written atomically (raybench.files).
_io_handler = None
_x11 = None  # Xlib, where the handler is set


def _one_line_on_lost_display() -> None:
    global _io_handler, _x11
    if _io_handler is not None or not os.environ.get("DISPLAY"):
        return
    try:
        x11 = ctypes.CDLL(ctypes.util.find_library("X11") or "libX11.so.6")
    except OSError:  # no Xlib (Wayland alone): nothing to answer for
        return
    x11.XSync.argtypes = [ctypes.c_void_p, ctypes.c_int]
    _x11 = x11
    display = os.environ["DISPLAY"]

    def lost(_connection) -> int:
        line = f"raybench: error: the window's display {display} was lost (its X server closed the connection)\n"
        os.write(2, one_line(line.rstrip("\n")).encode() + b"\n")
        os._exit(2)

    _io_handler = ctypes.CFUNCTYPE(ctypes.c_int, ctypes.c_void_p)(lost)
    x11.XSetIOErrorHandler(_io_handler)


def check_display_alive() -> None:
    """A round trip to the window's X server, before a draw asks the surface
    for a texture: a server gone is then met here, by Xlib, whose handler
    says it in one line. Met first by the Vulkan driver (the surface found
    unsupported), wgpu-native's fatal error handler aborted the process."""
    if _x11 is None:
        return
    import glfw

    display = glfw.get_x11_display()
    if display:
        _x11.XSync(display, 0)


def _glfw_message(warning) -> str:
    """pyGLFW's warnings read "(65550) b'X11: Failed to open display :5'": keep the words."""
    text = " ".join(str(warning).split())
    match = re.fullmatch(r"\(\d+\) b(['\"])(.*)\1", text)
    return match[2] if match else text


def surface_capabilities(context, adapter) -> dict:
    """The formats and usages the window's surface supports. rendercanvas does
    not expose them; read them from the wgpu context it wraps, or assume the
    least (the preferred format, drawing only) if that ever moves."""
    try:
        caps = context._wgpu_context._get_capabilities(adapter)
        return {"formats": list(caps["formats"]), "usages": int(caps["usages"])}
    except Exception:  # noqa: BLE001
        import wgpu

        return {"formats": [context.get_preferred_format(adapter)], "usages": int(wgpu.TextureUsage.RENDER_ATTACHMENT)}


def reconfigure_checks_display(context) -> None:
    """Make the surface's own reconfigure meet a lost display first. wgpu
    configures the surface again by itself when getting a texture finds it
    lost or outdated, which is what a dead X server makes it: that configure
    then asks the Vulkan driver, which finds the surface unsupported, and
    wgpu-native's fatal error handler aborts the process. A round trip to
    the server just before it (check_display_alive) lets Xlib's handler say
    it in one line instead. rendercanvas does not expose the wgpu context it
    wraps; where that ever moves, the round trip before each draw remains."""
    inner = getattr(context, "_wgpu_context", None)
    configure = getattr(inner, "_configure_screen_real", None)
    if configure is None:
        return

    def configure_if_alive(*args, **kwargs):
        check_display_alive()
        return configure(*args, **kwargs)

    inner._configure_screen_real = configure_if_alive


def screenshot_path(folder: Path) -> Path:
    """raybench-view-<date>-<time>.png in folder, never overwriting one."""
    stem = f"raybench-view-{datetime.datetime.now():%Y%m%d-%H%M%S}"
    path, n = folder / f"{stem}.png", 2
    while path.exists():
        path, n = folder / f"{stem}-{n}.png", n + 1
    return path


class ViewerWindow:
    def __init__(
        self, state: ViewerState, size: tuple[int, int], *, frames: int | None = None, screenshot: Path | None = None
    ):
        """frames: close after this many traced frames are shown, saving the last
        as screenshot (if given). P saves into the current folder."""
        import wgpu

        check_display()
        from rendercanvas.glfw import RenderCanvas, loop

        self.state = state
        self.frames = frames
        self.screenshot = screenshot
        self.saved: list[Path] = []
        self.failure: RaybenchError | None = None
        self.loop = loop
        self._listeners = []
        self._texture = None  # the surface texture, during a draw only
        try:
            self.canvas = RenderCanvas(
                size=size, title="raybench", update_mode="ondemand", min_fps=MIN_FPS, max_fps=MAX_FPS, vsync=False
            )
        except Exception as exc:  # noqa: BLE001
            raise RaybenchError(f"cannot open a window ({' '.join(str(exc).split())}); {SUGGEST}") from None
        try:
            self.context = self.canvas.get_wgpu_context()
            named = state.options.get("wgpu", {}).get("adapter")
            self.adapter, self.device = request_device(self.canvas, named)
            caps = surface_capabilities(self.context, self.adapter)
            self.format = choose_target_format(caps["formats"])
            # Read the screenshot from the surface itself where it allows copies; else
            # from an offscreen texture drawn the same way (TextureQuad.draw_offscreen).
            self.surface_readable = bool(caps["usages"] & wgpu.TextureUsage.COPY_SRC)
            usage = wgpu.TextureUsage.RENDER_ATTACHMENT | (wgpu.TextureUsage.COPY_SRC if self.surface_readable else 0)
            check_display_alive()
            self.context.configure(
                device=self.device, format=self.format.configure, usage=usage, view_formats=self.format.view_formats
            )
            reconfigure_checks_display(self.context)
            quad = TextureQuad(self.device, self.format.view)
            gpu_tracer = wgpu_tracer_here(state, self.device, self.adapter, named)
        except BaseException:
            self.canvas.close()
            self.context = None  # the surface, now: see run()
            raise
        self.drawer = FrameDrawer(state, self.device, quad, gpu_tracer, on_done=self._frame_ready)
        self.canvas.add_event_handler(
            self.handle_event, "key_down", "key_up", "pointer_down", "pointer_move", "pointer_up"
        )
        self.canvas.request_draw(self._draw)

    @property
    def quad(self) -> TextureQuad:
        return self.drawer.quad

    @property
    def gpu_tracer(self):
        """The wgpu tracer on the window's device (zero_copy.InWindowTracer), or None."""
        return self.drawer.gpu_tracer

    @property
    def worker(self):
        return self.drawer.worker

    # ------------------------------------------------------------------ running

    def run(self) -> None:
        """Show frames until the window is closed (Esc, the close button, or --frames)."""
        try:
            self.loop.run()
        finally:
            self.drawer.closing = True
            if not self.canvas.get_closed():
                self.canvas.close()
            self.drawer.close()
            # Release the surface now, while glfw and the X connection are up.
            # Left to the garbage collector (the window is in reference cycles)
            # it could go after glfw.terminate(), at exit say, and releasing a
            # surface then can crash the process (pygfx/pygfx#642).
            self.context = None
        if self.failure is not None:
            raise self.failure

    def close(self) -> None:
        """Close the window after the current draw (never inside one: the frame is still being presented)."""
        self.drawer.closing = True
        self.loop.call_soon(self.canvas.close)

    def add_frame_listener(self, listener) -> None:
        """listener(window, traced_frame) is called after each traced frame is
        drawn, while window.read_drawn() can still read it (tests and scripts)."""
        self._listeners.append(listener)

    # ------------------------------------------------------------------ events and frames

    def handle_event(self, event: dict) -> None:
        """The canvas's event handler: rendercanvas event dicts (tests call it too)."""
        action = self.state.handle_event(event)
        if action == "quit":
            self.close()
            return
        if action == "help" and self.state.help:
            print("\n".join(["raybench view keys:"] + ["  " + line for line in help_lines()]), flush=True)
        self.canvas.request_draw()  # the title, a screenshot, a new request after a stall: all at the next draw

    def _frame_ready(self) -> None:
        """From the worker thread: a frame (or a failure) waits to be shown."""
        self.loop.call_soon_threadsafe(self.canvas.request_draw)

    def _draw(self) -> None:
        # First the surface texture: if the window cannot be drawn now (hidden,
        # resizing) this raises and the finished frame stays for the next draw.
        check_display_alive()
        texture = self.context.get_current_texture()
        traced = self.drawer.draw(texture.create_view(format=self.format.view), *self.canvas.get_physical_size())
        self._texture = texture
        try:
            if traced is not None:
                for listener in list(self._listeners):
                    listener(self, traced)
            if self.state.screenshot_wanted:
                self.state.screenshot_wanted = False
                self._save(screenshot_path(Path.cwd()))
            if traced is not None and self.frames is not None and self.state.frames_shown >= self.frames:
                if self.screenshot is not None:
                    self.failure = self._save(self.screenshot)  # raised by run(): the caller asked for this file
                self.close()
        finally:
            self._texture = None
        self.canvas.set_title(self.state.title())
        self._trace_next()

    def read_drawn(self) -> np.ndarray:
        """The picture drawn in the current draw, as (H, W, 3) RGB bytes: read
        back from the window's surface, or, where the surface cannot be read,
        drawn again by the same pipeline into a texture of the same format."""
        if self._texture is None:
            raise RuntimeError("read_drawn() works only during a draw (in a frame listener)")
        if self.surface_readable:
            return self.quad.read(self._texture)
        width, height = self._texture.size[:2]
        return self.quad.draw_offscreen(width, height)

    def _save(self, path: Path) -> RaybenchError | None:
        """Write what was drawn as a PNG; the error, if it could not be (also shown in the title)."""
        try:
            write_atomic(path, png_bytes(self.read_drawn()))
        except RaybenchError as exc:
            self.state.say(str(exc))
            return exc
        self.saved.append(path)
        self.state.say(f"saved {path}")
        return None

    def _trace_next(self) -> None:
        if self.drawer.trace_next(*self.canvas.get_physical_size()):
            self.canvas.request_draw()  # the next draw traces the next frame (wgpu)
