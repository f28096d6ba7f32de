"""A frame's work in the viewer, without the canvas: what each draw does.

The window (window.py) owns the canvas: its surface, events, title and the
loop that schedules draws. Everything a draw does to a frame is here, given
the texture view to draw into and its size, so that the very same steps run
headless (benchmarks/viewer_frames.py times them with no window):

- cpu and cuda: the TraceWorker's thread traces through a Renderer; the draw
  takes the finished frame, hands it to the state, uploads it to the quad's
  texture and draws the quad; then the next frame goes to the worker, which
  traces it while this one is on screen;
- wgpu: the draw records the next frame's compute pass (zero_copy.py, the
  texture the quad draws) and the quad's render pass into one command buffer
  and submits it; the worker thread only waits for the GPU. The draw after
  that wait counts the frame and shows the same texture again, then asks for
  the next draw, which records the next pass.
"""

from __future__ import annotations

from ..errors import RaybenchError
from .gpu import TextureQuad
from .moving import MovingSpheres
from .state import ViewerState
from .worker import TracedFrame, TraceFailed, TraceWorker


def wgpu_tracer_here(state: ViewerState, device, adapter, named: str | None):
    """The wgpu tracer on the quad's device (zero_copy.InWindowTracer), where
    it may trace: on a GPU, or on a CPU driver (lavapipe) that was named
    (named: the adapter option given). Tells the state either way; None where
    it may not and the state starts on another device."""
    from ..backends.wgpu.adapters import describe_raw
    from .zero_copy import InWindowTracer

    described = describe_raw(adapter)
    if named is None and not described.is_gpu:
        reason = (
            f"device wgpu: the window's adapter, {described.label()}, is not a GPU; name it to trace on "
            f"it (--adapter {described.name.split(' ')[0]})"
        )
        if state.device == "wgpu":
            raise RaybenchError(reason)
        state.unavailable["wgpu"] = reason
        return None
    state.add_device("wgpu")
    return InWindowTracer(device, described)


class FrameDrawer:
    """The quad, the tracing thread and the in-window wgpu tracer, driven a draw at a time."""

    def __init__(self, state: ViewerState, device, quad: TextureQuad, gpu_tracer=None, on_done=None):
        """device: the wgpu device the quad draws with (the window's); gpu_tracer:
        a zero_copy.InWindowTracer on it, or None where wgpu cannot trace there;
        on_done: called from the worker's thread when a frame (or a failure)
        waits to be drawn (the window asks its loop for a draw)."""
        self.state = state
        self.device = device
        self.quad = quad
        self.gpu_tracer = gpu_tracer
        self.closing = False  # set when the window closes: no more frames are started
        self._gpu_idle = False  # the last draw found no wgpu frame to trace (stalled, failed)
        self.moving = MovingSpheres()  # --animate, for the frames wgpu traces here
        self.worker = TraceWorker(on_done=on_done)

    def draw(self, target_view, width: int, height: int) -> TracedFrame | None:
        """One draw into target_view (width x height: the window's size): the
        frame finished since the last draw, if any, handed to the state and
        shown; else, on wgpu, the next frame's pass recorded before the quad.
        Returns the traced frame shown for the first time, if any."""
        result = self.worker.handoff.take()
        traced = None
        if result is not None:
            self.state.on_traced(result)
            if isinstance(result, TracedFrame):
                if result.rgba is not None:  # None: a wgpu frame, already in the texture the quad draws
                    self.quad.upload(result.rgba)
                traced = result
        # One command buffer: a wgpu frame's compute pass, then the quad that draws its texture.
        encoder = self.device.create_command_encoder()
        gpu = self._encode_gpu_frame(encoder, width, height) if result is None else None
        self.quad.encode(encoder, target_view)
        self.device.queue.submit([encoder.finish()])
        if gpu is not None:
            # Shown once the GPU is done: the worker thread waits for it, the loop goes on.
            self.worker.submit(gpu[0], wait=self._gpu_waiter(*gpu))
        return traced

    def trace_next(self, width: int, height: int) -> bool:
        """After a draw: the next frame to the worker, where it may trace one.
        True when the next frame needs a draw of its own (wgpu's pass is
        recorded by a draw); the caller then asks for one."""
        if self.closing or not self.worker.handoff.may_trace():
            return False
        if self.state.device == "wgpu":
            return not self._gpu_idle
        if width < 1 or height < 1:
            return False  # minimised: nothing to trace for
        request = self.state.next_request(width, height)
        if request is not None:
            self.worker.submit(request)
        return False

    def close(self, timeout: float | None = None) -> None:
        """Start no more frames; stop the worker after the frame in flight, if any."""
        self.closing = True
        self.worker.close(timeout)

    def _gpu_waiter(self, request, compile_s, update_ms=None, update=None):
        """What the worker thread runs for a submitted wgpu frame: wait for it,
        and its TracedFrame (the pass's time) or TraceFailed."""
        tracer = self.gpu_tracer

        def wait():
            try:
                return TracedFrame(
                    request, tracer.frame(request), None, tracer.elapsed_ms(), compile_s, update_ms, update
                )
            except Exception as exc:  # noqa: BLE001 - shown in the title; the window must live on
                return TraceFailed(request, f"wgpu failed: {type(exc).__name__}: {exc}")

        return wait

    def _encode_gpu_frame(self, encoder, width: int, height: int):
        """Where frames come from wgpu and the worker is idle: record the next
        frame's compute pass and have the quad draw its texture. (request,
        compile seconds, update ms, update), or None when there is nothing to
        trace or it failed."""
        if (
            self.closing
            or self.state.device != "wgpu"
            or self.gpu_tracer is None
            or not self.worker.handoff.may_trace()
        ):
            return None  # not wgpu's turn: a frame in flight or waiting decides what follows
        # From here, no frame means no next draw on our own: the window's MIN_FPS
        # redraws and any input (which asks for a draw) try again.
        self._gpu_idle = True
        if width < 1 or height < 1:
            return None
        request = self.state.next_request(width, height)
        if request is None:
            return None
        try:
            compile_s = self.gpu_tracer.prepare(request)
            update_ms, update = self.moving.update(self.gpu_tracer.compute, request)
            self.gpu_tracer.encode(encoder, request)
        except RaybenchError as exc:
            self.state.on_traced(TraceFailed(request, str(exc)))
            return None
        except Exception as exc:  # noqa: BLE001 - shown in the title; the window must live on
            self.state.on_traced(TraceFailed(request, f"wgpu failed: {type(exc).__name__}: {exc}"))
            return None
        self.quad.show(self.gpu_tracer.compute.texture)
        self._gpu_idle = False
        return request, compile_s, update_ms, update
