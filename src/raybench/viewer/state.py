"""What the viewer knows and does, without a window or a thread.

handle_event() is the window's event handler: it takes rendercanvas event
dicts ({"event_type": "key_down", "key": "w", ...}), so tests drive it exactly
as the window does. next_request() says what to trace next, on_traced() takes a
finished frame (or a failure), and title() is the status line to show.
"""

from __future__ import annotations

import time

from .. import backends
from ..camera import Camera
from ..scene import Scene
from .bindings import binding_for
from .controls import Motion, travel_speed
from .overlay import Status, help_line, status_line, waiting_line
from .pacing import FrameStats
from .shading import LIGHT_MOVES, LIGHT_STEP_S, FirstShading, ShadingControl
from .spheres import SphereSupply
from .worker import TracedFrame, TraceFailed, TraceRequest

MESSAGE_S = 5.0  # how long a message stays in the title bar
MIN_COMPILE_NOTE_S = 0.1  # a compilation shorter than this was a cache hit: not news


class ViewerState:
    def __init__(
        self,
        scene: Scene,
        *,
        device: str,
        seed: int | None = None,
        options: dict | None = None,
        clock=time.perf_counter,
        devices=("cpu", "cuda"),
        shading: FirstShading | None = None,
        animate: bool = False,
    ):
        """device: "cpu", "cuda" or "wgpu" (already resolved); seed: that of a generated
        scene, None for a scene file; options: per device, e.g. {"cpu": {"threads": 4}};
        devices: those Tab cycles through (the window adds wgpu where it can trace on it);
        shading: the first frame's (None: the thesis's), as render() takes it;
        animate: the spheres move (viewer.moving), each request at the clock's time since now."""
        if device not in backends.DEVICES:
            raise ValueError(f"device must be one of {backends.DEVICES}, got {device!r}")
        self.devices = tuple(devices) + ((device,) if device not in devices else ())
        self.unavailable: dict[str, str] = {}  # device -> why it cannot trace here (the window says)
        self.clock = clock
        self.supply = SphereSupply(scene, seed)
        self.home = scene.camera or Camera()
        self.camera = self.home
        self.device = device  # where the next frame is traced
        self._working_device = device  # where frames last came from: the fallback for a failed switch
        self.options = {d: dict((options or {}).get(d, {})) for d in backends.DEVICES}
        # rows 0 to 2 of any kind's buffer: a sphere's centre, a triangle's first corner
        self.motion = Motion(travel_speed(self.supply.traced.buffer()[0:3].T, self.home))
        self.lighting = ShadingControl(shading, step=self.motion.speed * LIGHT_STEP_S)
        self.stats = FrameStats()
        self.shown: TracedFrame | None = None
        self.frames_shown = 0
        self.help = False
        self.quit = False
        self.screenshot_wanted = False
        self._message: str | None = None
        self._message_until = 0.0
        self._drag_from: tuple[float, float] | None = None
        self.requests_made = 0
        self.last_request: TraceRequest | None = None
        self._stalled_at: tuple[int, int] | None = None  # size at which the working device failed
        self._stall_reason = ""
        self._animation_start = clock() if animate else None

    # ------------------------------------------------------------------ input

    def handle_event(self, event: dict) -> str | None:
        """Apply one rendercanvas event; the action it triggered, if any (the
        window acts on "quit", "help" and "screenshot" too)."""
        kind = event.get("event_type")
        now = self.clock()
        if kind == "key_down":
            binding = binding_for(event.get("key"))
            if binding is None:
                return None
            self._stalled_at = None  # the user did something: worth trying again
            if binding.held:
                self.motion.keys.press(binding.action, now)
            else:
                self._act(binding.action, now)
            return binding.action
        if kind == "key_up":
            binding = binding_for(event.get("key"))
            if binding is not None and binding.held:
                self.motion.keys.release(binding.action, now)
            return None
        if kind == "pointer_down" and event.get("button") == 1:
            self._drag_from = (event["x"], event["y"])
        elif kind == "pointer_move" and self._drag_from is not None and 1 in event.get("buttons", ()):
            x, y = event["x"], event["y"]
            self.motion.drag(x - self._drag_from[0], y - self._drag_from[1])
            self._drag_from = (x, y)
            self._stalled_at = None
        elif kind == "pointer_up" and event.get("button") == 1:
            self._drag_from = None
        return None

    def _act(self, action: str, now: float) -> None:
        if action == "next_device":
            devices = self.devices
            self._switch(devices[(devices.index(self.device) + 1) % len(devices)])
        elif action == "device_cpu":
            self._switch("cpu")
        elif action == "device_cuda":
            self._switch("cuda")
        elif action == "device_wgpu":
            self._switch("wgpu")
        elif action == "more_spheres":
            self.say(self.supply.more())
        elif action == "fewer_spheres":
            self.supply.fewer()
        elif action == "ramp":
            self.say(self.supply.toggle_ramp())
        elif action == "toggle_shading":
            self.say(self.lighting.toggle())
        elif action in LIGHT_MOVES:
            self.say(self.lighting.move_light(action, self.supply.scene, self.camera))
        elif action == "reset":
            self.camera = self.home
            self.motion.clear(now)
            self.lighting.reset_light()
            self.say("view reset")
        elif action == "screenshot":
            self.screenshot_wanted = True
        elif action == "help":
            self.help = not self.help
        elif action == "quit":
            self.quit = True

    def add_device(self, device: str) -> None:
        """One more device for Tab (the window adds wgpu where it can trace on it)."""
        if device not in self.devices:
            self.devices += (device,)
        self.unavailable.pop(device, None)

    def _switch(self, device: str) -> None:
        if device == self.device:
            self.say(f"already on {device}")
            return
        if device in self.unavailable:
            self.say(f"{self.unavailable[device]} (staying on {self.device})")
            return
        self.device = device
        self.say(f"switching to {device}...")

    def say(self, message: str | None) -> None:
        if message:
            self._message = message
            self._message_until = self.clock() + MESSAGE_S

    # ------------------------------------------------------------------ frames

    def next_request(self, width: int, height: int) -> TraceRequest | None:
        """The next frame to trace, at the window's size; None while the device
        that should work has just failed at this size and nothing has changed."""
        if self._stalled_at == (width, height):
            return None
        self._stalled_at = None
        self.camera = self.motion.apply(self.camera, self.clock())
        scene, count, message = self.supply.frame_count()
        scene, shading = self.lighting.for_scene(scene)
        self.say(message)
        self.requests_made += 1
        self.last_request = TraceRequest(
            number=self.requests_made,
            device=self.device,
            scene=scene,
            count=count,
            camera=self.camera,
            width=width,
            height=height,
            options=self.options[self.device],
            shading=shading,
            time=None if self._animation_start is None else self.clock() - self._animation_start,
        )
        return self.last_request

    def on_traced(self, result: TracedFrame | TraceFailed) -> None:
        """A frame finished tracing (and is about to be drawn), or failed."""
        request = result.request
        if isinstance(result, TraceFailed):
            if request.device != self._working_device:
                # Asked for a device that cannot trace (cuda with no GPU): stay where frames come from.
                self.device = self._working_device
                self.say(f"{result.message} (staying on {self._working_device})")
            else:
                self._stalled_at = (request.width, request.height)
                self._stall_reason = f"stopped: {result.message} (resize or press a key to try again)"
            return
        previous = self.shown
        if previous is None or comparable(previous) != comparable(result):
            self.stats.reset()  # another device, size or shading: its times are not comparable
        if previous is not None and previous.frame.device != result.frame.device:
            self.say(f"now on {result.frame.device}")
        if result.compile_s is not None and result.compile_s >= MIN_COMPILE_NOTE_S:
            self.say(f"{result.frame.device} kernel compiled in {result.compile_s:.1f} s")
        self._working_device = result.frame.device
        self.shown = result
        self.frames_shown += 1
        self.stats.add(self.clock(), result.trace_ms, result.rays_cast)

    # ------------------------------------------------------------------ display

    def title(self) -> str:
        now = self.clock()
        if self.help:
            return help_line()
        message = self._message if now < self._message_until else None
        if self._stalled_at is not None:
            message = self._stall_reason  # stays until tracing goes on
        if self.shown is None:
            request = self.last_request
            size = (request.width, request.height) if request else (0, 0)
            return waiting_line(
                device=self.device,
                spheres=self.supply.count,
                width=size[0],
                height=size[1],
                message=message,
                noun=self.supply.noun,
            )
        shown = self.shown
        return status_line(
            Status(
                device=device_label(shown),
                spheres=shown.request.count,
                width=shown.frame.width,
                height=shown.frame.height,
                frame_ms=self.stats.frame_ms(now),
                fps=self.stats.fps(now),
                ramp=self.supply.ramping,
                message=message,
                shading=shading_label(shown),
                rays_per_s=self.stats.rays_per_s(now),
                noun=self.supply.noun,
                update=(shown.update, shown.update_ms) if shown.update is not None else None,
            )
        )


def comparable(shown: TracedFrame) -> tuple:
    """What frames must share for their times to be averaged together."""
    return shown.frame.device, shown.frame.width, shown.frame.height, shown.request.shading is None


def shading_label(shown: TracedFrame) -> str:
    """The shading of a frame, with what sets Whitted's cost."""
    shading = shown.request.shading
    if shading is None:
        return "thesis"
    return f"whitted, depth {shading.depth}, {shading.shadow_samples} shadow samples"


def device_label(shown: TracedFrame) -> str:
    """The device of a frame, with what sets its speed: the CPU's threads, a
    block shape other than the default, or that the GPU is numba's simulator."""
    device, options = shown.frame.device, shown.request.options
    if device == "cpu":
        from ..backends.cpu import default_threads

        return f"cpu, {options.get('threads') or default_threads()} threads"
    if device == "wgpu":
        # in the window's texture, no copy: the adapter tells a GPU from a CPU driver
        return f"wgpu on {shown.frame.adapter}, no copy"
    label = "cuda (numba simulator)" if backends.module("cuda").simulated() else "cuda"
    if "block" in options:
        label += f", block {options['block'][0]}x{options['block'][1]}"
    return label
