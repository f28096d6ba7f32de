"""The tracing thread: frames are traced here, off the window's event loop.

The thread traces through a raybench.Renderer, as a program would (and as
render(), the benchmark and the cluster's workers do); it never traces by
itself. It keeps one Renderer and replaces it when the device, size, scene,
options or shading change. Every Renderer is made, used and closed on this one
thread, which is what makes switching the device while a frame is in flight
safe: the switch only changes the next request, and a CUDA context never
crosses threads. (wgpu on the window's own GPU traces in the window instead,
into the texture it draws: zero_copy.py.)

The CPU kernels run with the GIL released (nogil), so the window stays
responsive while all cores trace; numba's CUDA simulator is pure Python and
shares the GIL, which makes the window slower to react but never blocks it.
"""

from __future__ import annotations

import threading
import time
from dataclasses import dataclass, field

import numpy as np

from .. import compiled
from ..camera import Camera
from ..errors import RaybenchError
from ..lighting import Shading
from ..render import Frame, Renderer
from ..scene import Scene
from .moving import MovingSpheres
from .pacing import Handoff


@dataclass(frozen=True)
class TraceRequest:
    number: int
    device: str
    scene: Scene
    count: int
    camera: Camera
    width: int
    height: int
    options: dict = field(default_factory=dict)  # the device's own (cpu: threads; cuda: block)
    shading: Shading | None = None  # Whitted shading's arrays (of this scene); None: the thesis's shading
    time: float | None = None  # --animate: the spheres where animate.Orbits puts them at this time (s)


@dataclass
class TracedFrame:
    request: TraceRequest
    frame: Frame  # or a zero_copy.DrawnFrame: traced by wgpu into the window's texture
    rgba: np.ndarray | None  # (H, W, 4) uint8: the frame as the texture wants it (None: already there)
    trace_ms: float  # Renderer.render: camera basis, trace, copy to the host (wgpu in the window: the pass)
    compile_s: float | None  # set on the first frame of a new tracer
    update_ms: float | None = None  # --animate: the tree's update before the trace (not in trace_ms)
    update: str | None = None  # its kind: "refit" or "build" (None: brute force, or not animated)

    @property
    def rays_cast(self) -> int:
        """The rays the frame cast: under Whitted shading every kind the
        kernel counted (primary, shadow, reflection, refraction); under the
        thesis's, one primary ray a pixel."""
        counted = getattr(self.frame, "rays", None)
        return sum(counted.values()) if counted else self.frame.width * self.frame.height


@dataclass
class TraceFailed:
    request: TraceRequest
    message: str


def to_rgba(image: np.ndarray) -> np.ndarray:
    """(H, W, 3) RGB -> (H, W, 4) RGBA with opaque alpha: textures have no 3-byte
    formats. Done here so the event loop only copies bytes to the GPU."""
    rgba = np.empty(image.shape[:2] + (4,), dtype=np.uint8)
    _pack_rgba(np.ascontiguousarray(image), rgba)
    return rgba


@compiled.njit(nogil=True)
def _pack_rgba(image, rgba):
    # A loop, not NumPy's rgba[..., :3] = image: that strided copy took as long
    # as cuda's trace of the frame (docs/scenes.md#the-viewer).
    height, width = image.shape[:2]
    for y in range(height):
        for x in range(width):
            rgba[y, x, 0] = image[y, x, 0]
            rgba[y, x, 1] = image[y, x, 1]
            rgba[y, x, 2] = image[y, x, 2]
            rgba[y, x, 3] = 255


class TraceWorker:
    """One thread that traces the requests given to it, one at a time.

    on_done is called from the worker thread after each frame (or failure) is
    handed over; it must be thread-safe (the window passes the loop's
    call_soon_threadsafe)."""

    def __init__(self, on_done=None):
        self.handoff = Handoff()
        self._on_done = on_done
        self._wake = threading.Condition()
        self._request: TraceRequest | None = None
        self._closing = False
        self._renderer = None
        self._renderer_key = None
        self._renderer_scene = None
        self._moving = MovingSpheres()
        self._thread = threading.Thread(target=self._run, name="raybench-trace", daemon=True)
        self._thread.start()

    def submit(self, request: TraceRequest, wait=None) -> None:
        """Trace this next; only when handoff.may_trace(). wait: a frame already
        submitted to a GPU by the window (wgpu): the thread only waits for it,
        wait() returning its TracedFrame or TraceFailed, so the window never does."""
        self.handoff.start(request)
        with self._wake:
            self._request = (request, wait)
            self._wake.notify()

    def close(self, timeout: float | None = None) -> None:
        """Stop after the frame in flight, if any, and release the Renderer."""
        with self._wake:
            self._closing = True
            self._wake.notify()
        self._thread.join(timeout)

    def _run(self) -> None:
        try:
            while True:
                with self._wake:
                    while self._request is None and not self._closing:
                        self._wake.wait()
                    if self._closing:
                        return
                    (request, wait), self._request = self._request, None
                self.handoff.finish(self._trace(request) if wait is None else wait())
                if self._on_done is not None:
                    try:
                        self._on_done()
                    except Exception:  # noqa: BLE001
                        pass  # the window is gone; nobody is waiting for this frame
        finally:
            self._drop_renderer()

    def _trace(self, request: TraceRequest) -> TracedFrame | TraceFailed:
        try:
            compile_s = self._ensure_renderer(request)
            update_ms, update = self._moving.update(self._renderer, request)
            start = time.perf_counter()
            # hits=False: the window never reads them, so a frame it holds keeps none
            frame = self._renderer.render(request.camera, hits=False, count=request.count)
            trace_ms = (time.perf_counter() - start) * 1e3
            return TracedFrame(request, frame, to_rgba(frame.image), trace_ms, compile_s, update_ms, update)
        except RaybenchError as exc:
            self._drop_renderer()
            return TraceFailed(request, str(exc))
        except Exception as exc:  # noqa: BLE001 - shown in the title; the window must live on
            self._drop_renderer()
            return TraceFailed(request, f"{request.device} failed: {type(exc).__name__}: {exc}")

    def _ensure_renderer(self, request: TraceRequest) -> float | None:
        """Make the Renderer this request needs, if it is not the one held; the
        seconds its compilation took (None if it was already there)."""
        key = (request.device, id(request.scene), id(request.shading), request.width, request.height)
        key += (tuple(sorted(request.options.items())),)
        if key == self._renderer_key:
            return None
        self._drop_renderer()
        shading = "thesis" if request.shading is None else request.shading
        renderer = Renderer(
            request.scene, request.width, request.height, request.device, shading=shading, **request.options
        )
        try:
            compile_s = renderer.compile()
        except BaseException:
            renderer.close()
            raise
        # The scene and shading are held with the key: their id()s must not be reused while the key is.
        self._renderer, self._renderer_key, self._renderer_scene = renderer, key, (request.scene, request.shading)
        return compile_s

    def _drop_renderer(self) -> None:
        if self._renderer is not None:
            self._renderer.close()
        self._renderer, self._renderer_key, self._renderer_scene = None, None, None
