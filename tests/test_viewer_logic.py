"""The viewer's logic without a window: keys to camera motion, +/- and the ramp,
frame pacing and statistics, the title bar, and the tracing thread.

Events are rendercanvas-style dicts given to ViewerState.handle_event, the very
handler the window registers; time is a fake clock the tests advance.
"""

from __future__ import annotations

import math
import threading
import time

import numpy as np
import pytest

import raybench
from raybench import Camera, Light, Scene, cli, random_spheres, viewer
from raybench.backends import cuda as cuda_backend
from raybench.cli import run
from raybench.layout import KINDS, P_LIGHTS
from raybench.lighting import Shading
from raybench.scene import RAMP
from raybench.viewer import bindings, controls, overlay
from raybench.viewer.pacing import FrameStats, Handoff
from raybench.viewer.shading import LIGHT_STEP_S, FirstShading, ShadingControl
from raybench.viewer.spheres import SphereSupply
from raybench.viewer.state import ViewerState
from raybench.viewer.worker import TracedFrame, TraceFailed, TraceRequest, TraceWorker, to_rgba


class Clock:
    def __init__(self, t=100.0):
        self.t = t

    def __call__(self):
        return self.t

    def advance(self, seconds):
        self.t += seconds


def key(name, kind="key_down"):
    return {"event_type": kind, "key": name, "modifiers": ()}


def pointer(kind, x, y, button=1, buttons=(1,)):
    return {
        "event_type": kind,
        "x": x,
        "y": y,
        "button": button,
        "buttons": buttons,
        "modifiers": (),
        "ntouches": 0,
        "touches": {},
    }


def make_state(n=20, seed=0, device="cpu", **kwargs):
    clock = Clock()
    state = ViewerState(random_spheres(n, seed), device=device, seed=seed, clock=clock, **kwargs)
    return state, clock


def close_to(a, b, tol=1e-9):
    return np.allclose(np.asarray(a, float), np.asarray(b, float), atol=tol, rtol=0)


def fake_traced(request, device=None, trace_ms=10.0, compile_s=None, rays=None):
    """A TracedFrame for request without tracing (for state and title tests);
    rays: the frame's rays by kind, as a Whitted frame has them."""
    image = np.zeros((request.height, request.width, 3), np.uint8)
    frame = raybench.Frame(
        image=image, hits=np.full(image.shape[:2], -1, np.int32), device=device or request.device, rays=rays
    )
    return TracedFrame(request, frame, to_rgba(image), trace_ms, compile_s)


# --------------------------------------------------------------------------- key bindings


def test_every_binding_has_a_distinct_key_and_a_handler():
    keys = [k.lower() for b in bindings.BINDINGS for k in b.keys]
    assert len(keys) == len(set(keys))
    state, _ = make_state()
    for b in bindings.BINDINGS:
        if b.action in ("quit",):
            continue
        assert state.handle_event(key(b.keys[0])) == b.action
        state.handle_event(key(b.keys[0], "key_up"))


def test_keys_are_matched_case_blind_and_unknown_keys_do_nothing():
    assert bindings.binding_for("W").action == "forward"  # W with Shift held
    assert bindings.binding_for("escape") is bindings.binding_for("Escape")
    assert bindings.binding_for("=").action == "more_spheres"  # the + key without Shift
    assert bindings.binding_for("F7") is None
    assert bindings.binding_for(None) is None
    state, _ = make_state()
    assert state.handle_event(key("F7")) is None
    assert state.handle_event({"event_type": "resize", "width": 5, "height": 5}) is None


def test_help_lists_every_key_and_the_mouse(capsys):
    lines = bindings.help_lines()
    text = "\n".join(lines)
    for label in [
        "W",
        "A",
        "S",
        "D",
        "Tab",
        "+",
        "-",
        "T",
        "G",
        "J",
        "L",
        "I",
        "K",
        "U",
        "O",
        "R",
        "P",
        "H",
        "Esc",
        "drag",
    ]:
        assert any(line.split()[0] == label or line.startswith(label + " ") for line in lines), label
    assert "test 7" in text and "whitted" in text and "light" in text
    assert "G shading" in bindings.help_summary() and "IJKL/UO light" in bindings.help_summary()
    code = run(["view", "--help"])
    out = capsys.readouterr().out
    assert code == 0
    for line in lines:
        assert line in out, line


# --------------------------------------------------------------------------- camera motion


def test_moves_follow_the_cameras_own_axes():
    cam = Camera()
    forward, right, up = controls.axes(cam)
    assert close_to(forward, [0, 0, 1]) and close_to(up, [0, 1, 0])
    # right = cross(forward, up): the direction of increasing pixel x in camera.py's convention.
    assert close_to(right, np.cross([0, 0, 1], [0, 1, 0]))
    ahead = controls.moved(cam, 2.0, 0.0)
    assert close_to(ahead.position, [0, 0, 2]) and close_to(ahead.look_at, [0, 0, 3])
    aside = controls.moved(cam, 0.0, 1.5)
    assert close_to(aside.position, 1.5 * right)
    assert close_to(controls.axes(aside)[0], forward)  # moving never turns


def test_turning_right_looks_where_right_was_and_keeps_the_horizon():
    cam = Camera(position=(1, 2, 3), look_at=(1, 2, 13))
    _, right, _ = controls.axes(cam)
    turned = controls.turned(cam, 90.0, 0.0)
    assert close_to(controls.axes(turned)[0], right)
    assert turned.position == cam.position
    assert math.isclose(np.linalg.norm(np.subtract(turned.look_at, turned.position)), 10.0)
    back = controls.turned(turned, -90.0, 0.0)
    assert close_to(back.look_at, cam.look_at, 1e-9)


def test_looking_up_stops_short_of_straight_up():
    cam = controls.turned(Camera(), 0.0, 30.0)
    f, _, up = controls.axes(cam)
    assert math.isclose(math.degrees(math.asin(f @ up)), 30.0)
    steep = controls.turned(cam, 0.0, 500.0)
    f, _, up = controls.axes(steep)
    assert math.isclose(math.degrees(math.asin(f @ up)), controls.MAX_ELEVATION_DEG)
    steep.basis(8, 8)  # still a valid camera


def test_held_keys_count_the_time_held_not_the_frames():
    keys = controls.HeldKeys()
    keys.press("forward", 0.0)
    keys.press("forward", 0.2)  # key repeat: the first press counts
    assert keys.take(0.3) == {"forward": pytest.approx(0.3)}
    keys.release("forward", 0.5)
    keys.press("left", 0.6)
    keys.release("left", 0.7)
    held = keys.take(5.0)  # one slow frame later
    assert held == {"forward": pytest.approx(0.2), "left": pytest.approx(0.1)}
    assert keys.take(6.0) == {}
    keys.release("back", 7.0)  # a release without a press (focus changed) is ignored
    assert keys.take(8.0) == {}


def test_w_held_moves_as_far_whatever_the_frame_rate():
    """Half a second of W moves the camera speed/2 forward, whether the device
    made one frame meanwhile or fifty."""
    ends = []
    for frames in (1, 50):
        state, clock = make_state()
        start = state.camera.position
        state.handle_event(key("w"))
        for _ in range(frames):
            clock.advance(0.5 / frames)
            state.next_request(16, 12)
        state.handle_event(key("w", "key_up"))
        state.next_request(16, 12)
        ends.append(np.subtract(state.camera.position, start))
        assert close_to(ends[-1], [0, 0, state.motion.speed * 0.5], 1e-9)
    assert close_to(ends[0], ends[1], 1e-9)


def test_wasd_directions_and_opposite_keys_cancel():
    for name, direction in [("w", [0, 0, 1]), ("s", [0, 0, -1]), ("d", [-1, 0, 0]), ("a", [1, 0, 0])]:
        state, clock = make_state()
        state.handle_event(key(name))
        clock.advance(1.0)
        state.next_request(16, 12)
        assert close_to(state.camera.position, np.multiply(direction, state.motion.speed)), name
    state, clock = make_state()
    state.handle_event(key("w"))
    state.handle_event(key("s"))
    clock.advance(1.0)
    request = state.next_request(16, 12)
    assert request.camera is state.home


def test_mouse_drag_turns_and_a_plain_move_does_not():
    state, _ = make_state()
    state.handle_event(pointer("pointer_move", 10, 10, button=0, buttons=()))  # hover
    state.next_request(16, 12)
    assert state.camera is state.home
    state.handle_event(pointer("pointer_down", 10, 10))
    state.handle_event(pointer("pointer_move", 10 + 360 / controls.DRAG_DEG_PER_PIXEL / 4, 10))  # 90 degrees right
    state.handle_event(pointer("pointer_up", 0, 0))
    state.next_request(16, 12)
    _, right, _ = controls.axes(state.home)
    assert close_to(controls.axes(state.camera)[0], right)
    state.handle_event(pointer("pointer_down", 0, 100))
    state.handle_event(pointer("pointer_move", 0, 100 - 20 / controls.DRAG_DEG_PER_PIXEL))  # drag up: look up 20
    state.next_request(16, 12)
    f, _, up = controls.axes(state.camera)
    assert math.isclose(math.degrees(math.asin(f @ up)), 20.0)


def test_arrow_keys_turn_at_a_fixed_rate():
    state, clock = make_state()
    state.handle_event(key("ArrowLeft"))
    clock.advance(0.5)
    state.handle_event(key("ArrowLeft", "key_up"))
    state.next_request(16, 12)
    f, right, _ = controls.axes(state.camera)
    angle = math.degrees(math.atan2(f @ controls.axes(state.home)[1], f @ controls.axes(state.home)[0]))
    assert math.isclose(angle, -controls.TURN_DEG_PER_S * 0.5)


def test_reset_gives_back_the_home_camera_exactly():
    state, clock = make_state()
    state.handle_event(key("d"))
    state.handle_event(pointer("pointer_down", 0, 0))
    state.handle_event(pointer("pointer_move", 40, 30))
    clock.advance(0.7)
    assert state.next_request(16, 12).camera != state.home
    state.handle_event(key("r"))  # D is still down: reset forgets the motion so far
    request = state.next_request(16, 12)
    assert request.camera is state.home
    assert np.array_equal(request.camera.basis(16, 12), state.home.basis(16, 12))


def test_travel_speed_scales_with_the_scene():
    near = controls.travel_speed(np.array([[0, 0, 2.0], [0, 0, 4.0], [0, 0, 6.0]]), Camera())
    far = controls.travel_speed(np.array([[0, 0, 200.0], [0, 0, 400.0], [0, 0, 600.0]]), Camera())
    assert near == pytest.approx(2.0) and far == pytest.approx(200.0)
    assert controls.travel_speed(np.zeros((0, 3)), Camera()) == 1.0


# --------------------------------------------------------------------------- +/- and the ramp


def test_first_frame_is_the_view_raybench_render_draws():
    scene_camera = Camera(position=(0, 1, -2), look_at=(0, 0, 10), fov_deg=50)
    spheres = random_spheres(15, 3)
    scene = Scene(spheres.centers, spheres.radii, spheres.colors, scene_camera)
    state = ViewerState(scene, device="cpu", seed=None, clock=Clock())
    request = state.next_request(40, 30)
    assert request.camera is scene_camera and request.scene is scene and request.count == 15
    generated, _ = make_state(n=25, seed=7)
    request = generated.next_request(40, 30)
    assert request.count == 25 and request.camera == Camera()
    assert np.array_equal(request.scene.spheres, random_spheres(25, 7).spheres)


def test_plus_and_minus_on_random_spheres():
    supply = SphereSupply(random_spheres(25, 4), seed=4)
    first = supply.scene
    supply.fewer()
    supply.fewer()
    assert supply.count == 5 and supply.scene is first  # a prefix of the same scene
    supply.more()
    supply.more()
    assert supply.count == 25 and supply.scene is first
    assert supply.more() is None
    # Past the end: what `raybench render --spheres 35 --seed 4` draws.
    assert supply.count == 35 and np.array_equal(supply.scene.spheres, random_spheres(35, 4).spheres)
    for _ in range(5):
        supply.fewer()
    assert supply.count == 0


def test_plus_and_the_ramp_keep_random_materials():
    """--spheres N --materials: the scenes made past the end and for the ramp
    are what `raybench render --spheres M --materials` draws, lights and all."""
    supply = SphereSupply(random_spheres(25, 4, materials=True), seed=4)
    supply.more()
    expected = random_spheres(35, 4, materials=True)
    assert np.array_equal(supply.scene.spheres, expected.spheres)
    assert supply.scene.materials == expected.materials and supply.scene.lights == expected.lights
    supply.toggle_ramp()
    assert supply.scene.materials == random_spheres(RAMP[1], 4, materials=True).materials
    plain = SphereSupply(random_spheres(25, 4), seed=4)
    plain.more()
    assert plain.scene.materials is None and plain.scene.lights == ()


def test_plus_on_a_scene_file_stops_at_its_spheres():
    supply = SphereSupply(random_spheres(25, 4), seed=None)
    supply.fewer()
    assert supply.more() is None and supply.count == 25
    message = supply.more()
    assert supply.count == 25 and "25 spheres" in message


def test_ramp_is_test_7_one_step_per_frame():
    supply = SphereSupply(random_spheres(20, 2), seed=2)
    assert "ramp" in supply.toggle_ramp()
    counts, messages = [], []
    while True:
        scene, count, message = supply.frame_count()
        counts.append(count)
        if message:
            messages.append(message)
            break
    first, last, step = RAMP
    assert counts == list(range(first, last + 1, step))  # the frame of 1000 spheres says it is done
    assert np.array_equal(scene.spheres, random_spheres(last, 2).spheres)  # test 7's scene
    assert not supply.ramping and "done" in messages[0]
    # T during the ramp stops it where it is.
    supply.toggle_ramp()
    supply.frame_count()
    supply.frame_count()
    assert "stopped" in supply.toggle_ramp() and supply.count == first + 2 * step
    assert supply.frame_count()[1] == first + 2 * step


def test_ramp_over_a_small_scene_file():
    supply = SphereSupply(random_spheres(25, 4), seed=None)
    supply.toggle_ramp()
    assert [supply.frame_count()[1] for _ in range(4)] == [10, 20, 25, 25]
    assert not supply.ramping


def test_keys_drive_the_sphere_count_of_the_next_request():
    state, _ = make_state(n=20)
    state.handle_event(key("="))
    assert state.next_request(8, 6).count == 30
    state.handle_event(key("-"))
    state.handle_event(key("-"))
    assert state.next_request(8, 6).count == 10
    state.handle_event(key("t"))
    assert [state.next_request(8, 6).count for _ in range(3)] == [10, 20, 30]


# --------------------------------------------------------------------------- devices, frames, title


def test_tab_cycles_devices_and_a_failed_switch_stays_on_the_working_one():
    state, _ = make_state()
    state.on_traced(fake_traced(state.next_request(8, 6)))
    state.handle_event(key("Tab"))
    assert state.device == "cuda"
    request = state.next_request(8, 6)
    assert request.device == "cuda"
    state.on_traced(TraceFailed(request, "device cuda: no usable NVIDIA GPU"))
    assert state.device == "cpu"
    assert "no usable NVIDIA GPU" in state.title() and "staying on cpu" in state.title()
    assert state.next_request(8, 6).device == "cpu"
    state.handle_event(key("2"))
    assert state.device == "cuda"
    state.handle_event(key("1"))
    assert state.device == "cpu"


def test_wgpu_joins_the_cycle_only_where_the_window_can_trace_on_it():
    state, _ = make_state()
    state.unavailable["wgpu"] = "device wgpu: the window's adapter, llvmpipe (Vulkan, CPU), is not a GPU"
    state.handle_event(key("3"))
    assert state.device == "cpu" and "not a GPU" in state.title() and "staying on cpu" in state.title()
    state.handle_event(key("Tab"))
    state.handle_event(key("Tab"))
    assert state.device == "cpu"  # cpu -> cuda -> cpu: wgpu is not in the cycle
    state.add_device("wgpu")
    state.handle_event(key("3"))
    assert state.device == "wgpu" and state.next_request(8, 6).device == "wgpu"
    state.handle_event(key("Tab"))
    assert state.device == "cpu"


def test_switch_while_a_frame_is_in_flight_labels_frames_by_where_they_were_traced():
    state, _ = make_state()
    cpu_request = state.next_request(8, 6)  # in flight on the CPU ...
    state.handle_event(key("Tab"))  # ... when the user switches
    state.on_traced(fake_traced(cpu_request))  # it is still shown, as a cpu frame
    assert state.title().split("  |  ")[1].startswith("cpu")
    cuda_request = state.next_request(8, 6)
    assert cuda_request.device == "cuda"
    state.on_traced(fake_traced(cuda_request))
    assert "now on cuda" in state.title()


def test_a_failure_on_the_working_device_waits_for_input_or_a_new_size():
    state, _ = make_state()
    request = state.next_request(8, 6)
    state.on_traced(TraceFailed(request, "size: too big"))
    assert "stopped: size: too big" in state.title()
    assert state.next_request(8, 6) is None  # the same would fail again
    assert state.next_request(9, 6) is not None  # resized
    state.on_traced(TraceFailed(state.last_request, "size: too big"))
    assert state.next_request(9, 6) is None
    state.handle_event(key("-"))
    assert state.next_request(9, 6) is not None  # the user changed something
    assert "stopped" not in state.title()


def test_title_shows_what_is_on_screen():
    state, clock = make_state(n=1234, options={"cpu": {"threads": 3}})
    waiting = state.title()
    assert "1,234 spheres" in waiting and "compiling" in waiting
    for _ in range(5):
        state.on_traced(fake_traced(state.next_request(320, 200), trace_ms=20.0, compile_s=None))
        clock.advance(0.05)
    title = state.title()
    parts = title.split("  |  ")
    assert parts[:5] == ["raybench", "cpu, 3 threads", "1,234 spheres", "320x200", "frame 20.0 ms"]
    assert parts[5] == "20.0 fps"
    state.handle_event(key("t"))
    assert "ramp" in state.title().split("  |  ")
    state.handle_event(key("h"))
    assert state.title() == overlay.help_line()
    state.handle_event(key("h"))
    assert state.title().startswith("raybench  |  cpu")


def test_messages_expire():
    state, clock = make_state()
    state.on_traced(fake_traced(state.next_request(8, 6)))
    state.handle_event(key("r"))
    assert "view reset" in state.title()
    clock.advance(10)
    assert "view reset" not in state.title()


def test_compile_time_is_reported_apart_from_frame_times():
    state, _ = make_state()
    state.on_traced(fake_traced(state.next_request(8, 6), trace_ms=4.0, compile_s=2.5))
    title = state.title()
    assert "compiled in 2.5 s" in title and "frame 4.0 ms" in title


def test_quit_screenshot_and_help_flags():
    state, _ = make_state()
    assert state.handle_event(key("Escape")) == "quit" and state.quit
    assert state.handle_event(key("p")) == "screenshot" and state.screenshot_wanted
    assert state.handle_event(key("H")) == "help" and state.help


def test_status_line_formats():
    line = overlay.status_line(
        overlay.Status(
            device="cuda", spheres=1000, width=1680, height=1050, frame_ms=1234.5, fps=0.81, ramp=False, message=None
        )
    )
    assert line == "raybench  |  cuda  |  1,000 spheres  |  1680x1050  |  frame 1.23 s  |  0.8 fps"
    line = overlay.status_line(
        overlay.Status(device="cpu", spheres=0, width=8, height=6, frame_ms=None, fps=None, ramp=True, message="hello")
    )
    assert line.endswith("frame - ms  |  - fps  |  ramp  |  hello")


# --------------------------------------------------------------------------- shading and the light


def lit_file_scene():
    """A scene file's scene: a few spheres, two lights, its own camera looking along +x."""
    spheres = random_spheres(12, 9, materials=True)
    lights = [Light(position=(1.0, 5.0, -2.0), radius=0.5), Light(position=(-3.0, 2.0, 0.0), color=(0.5, 0.5, 1.0))]
    camera = Camera(position=(-10, 0, 15), look_at=(0, 0, 15))
    return Scene(spheres.centers, spheres.radii, spheres.colors, camera, materials=spheres.materials, lights=lights)


def same_shading(a: Shading, b: Shading) -> bool:
    return (a.depth, a.shadow_samples) == (b.depth, b.shadow_samples) and all(
        np.array_equal(getattr(a, k), getattr(b, k)) for k in ("materials", "lights", "pattern", "params")
    )


def test_g_toggles_the_shading_of_the_next_request():
    state, _ = make_state(n=20, seed=3, shading=FirstShading(depth=None))
    scene = state.supply.scene
    assert state.next_request(8, 6).shading is None  # the thesis's shading by default
    assert state.handle_event(key("g")) == "toggle_shading"
    request = state.next_request(8, 6)
    assert request.scene is scene and same_shading(request.shading, Shading.of(scene))
    assert "shading: whitted" in state.title()
    assert state.next_request(8, 6).shading is request.shading  # kept: the tracer is kept too
    state.handle_event(key("G"))  # with Shift
    assert state.next_request(8, 6).shading is None and "shading: thesis" in state.title()
    # --shading whitted --depth 2 --shadow-samples 3: the first request is render()'s Whitted frame.
    lit = random_spheres(15, 2, materials=True)
    state = ViewerState(lit, device="cpu", seed=2, clock=Clock(), shading=FirstShading("whitted", 2, 3))
    request = state.next_request(8, 6)
    assert request.scene is lit and same_shading(request.shading, Shading.of(lit, 2, 3))
    state.handle_event(key("g"))
    assert state.next_request(8, 6).shading is None
    state.handle_event(key("g"))
    assert same_shading(state.next_request(8, 6).shading, Shading.of(lit, 2, 3))  # depth and samples kept


def test_whitted_without_lights_is_traced_and_the_light_keys_say_why_nothing_moves():
    state, _ = make_state(n=20)  # random spheres without --materials: no lights
    state.handle_event(key("g"))
    request = state.next_request(8, 6)
    assert request.shading is not None and request.scene is state.supply.scene
    assert request.shading.params[P_LIGHTS] == 0
    state.handle_event(key("j"))
    assert "no lights" in state.title()
    assert state.next_request(8, 6).scene is request.scene


def test_light_keys_move_the_first_light_in_the_cameras_frame():
    scene = lit_file_scene()
    state = ViewerState(scene, device="cpu", seed=None, clock=Clock(), shading=FirstShading("whitted"))
    step = state.motion.speed * LIGHT_STEP_S
    assert state.lighting.step == step > 0
    forward, right, up = controls.axes(scene.camera)  # forward is +x here, right -z, up +y
    start = np.array(scene.lights[0].position)
    for name, direction in [("l", right), ("j", -right), ("i", up), ("k", -up), ("u", forward), ("o", -forward)]:
        state.handle_event(key(name))
        request = state.next_request(8, 6)
        moved = request.scene.lights[0]
        assert close_to(moved.position, start + step * direction), name
        assert "light at" in state.title()
        # only the first light's position: the spheres' bits, materials and the other lights stay
        assert moved.color == scene.lights[0].color and moved.radius == scene.lights[0].radius
        assert request.scene.lights[1:] == scene.lights[1:]
        assert np.array_equal(request.scene.spheres, scene.spheres) and request.scene.materials == scene.materials
        assert request.scene.camera == scene.camera
        # the Shading is that of the scene with the moved light, as render() would make it
        assert same_shading(request.shading, Shading.of(request.scene))
        assert not np.array_equal(request.shading.lights, Shading.of(scene).lights)
        state.handle_event(key(name, "key_up"))
        state.handle_event(key({"l": "j", "j": "l", "i": "k", "k": "i", "u": "o", "o": "u"}[name]))
        assert close_to(state.lighting.offset, np.zeros(3), 1e-9)
    state.handle_event(key("l"))
    state.handle_event(key("l"))
    request = state.next_request(8, 6)
    assert close_to(request.scene.lights[0].position, start + 2 * step * right)
    assert state.next_request(8, 6).shading is request.shading  # nothing new: the same Shading, the same tracer
    state.handle_event(key("r"))  # reset: the view and the light
    request = state.next_request(8, 6)
    assert request.scene is scene and same_shading(request.shading, Shading.of(scene))


def test_the_light_moves_under_the_thesis_shading_and_shows_under_whitted():
    scene = lit_file_scene()
    state = ViewerState(scene, device="cpu", seed=None, clock=Clock())
    state.handle_event(key("i"))
    request = state.next_request(8, 6)
    assert request.scene is scene and request.shading is None  # the thesis's frame does not change
    assert "whitted shading (G)" in state.title()
    state.handle_event(key("g"))
    request = state.next_request(8, 6)
    _, _, up = controls.axes(scene.camera)
    assert close_to(request.scene.lights[0].position, np.add(scene.lights[0].position, state.lighting.step * up))


def test_the_light_moves_with_the_random_scene_past_its_end():
    state, _ = make_state(n=20, seed=1, shading=FirstShading("whitted"))
    state.supply = SphereSupply(random_spheres(20, 1, materials=True), seed=1)
    state.handle_event(key("i"))
    state.handle_event(key("="))  # a new scene of 30 spheres: the light stays where it was moved
    request = state.next_request(8, 6)
    assert request.count == 30 and len(request.scene) == 30
    expected = np.add(random_spheres(30, 1, materials=True).lights[0].position, [0, state.lighting.step, 0])
    assert close_to(request.scene.lights[0].position, expected)


def test_a_light_step_out_of_bounds_is_refused_in_the_title():
    control = ShadingControl(FirstShading("whitted"), step=2e15)
    scene = lit_file_scene()
    message = control.move_light("light_up", scene, scene.camera)
    assert message.startswith("the light stays: ") and "position" in message
    assert not control.offset.any() and control.for_scene(scene)[0] is scene


def test_title_shows_the_shading_and_rays_per_second():
    state, clock = make_state(n=20, seed=0)
    for _ in range(3):  # the thesis's shading: one primary ray a pixel
        state.on_traced(fake_traced(state.next_request(100, 50), trace_ms=2.0))
        clock.advance(0.1)
    parts = state.title().split("  |  ")
    assert parts[6:8] == ["thesis", "2.5 M rays/s"]  # 5,000 rays in 2 ms
    state.handle_event(key("g"))
    counts = [{"primary": 5000, "shadow": 12000, "reflection": 2000, "refraction": 1000}, None]
    counts[1] = {k: 2 * v for k, v in counts[0].items()}
    state.on_traced(fake_traced(state.next_request(100, 50), trace_ms=4.0, rays=counts[0]))
    clock.advance(0.1)
    parts = state.title().split("  |  ")
    assert parts[6:8] == ["whitted, depth 5, 4 shadow samples", "5 M rays/s"]  # 20,000 in 4 ms: every kind
    state.on_traced(fake_traced(state.next_request(100, 50), trace_ms=6.0, rays=counts[1]))
    clock.advance(0.1)
    assert state.title().split("  |  ")[7] == "6 M rays/s"  # 60,000 rays in 10 ms: the thesis's frames are gone
    clock.advance(5)
    assert state.title().split("  |  ")[7] == "6.67 M rays/s"  # nothing for a while: the last frame's


def test_rays_per_second_formats():
    line = overlay.status_line(
        overlay.Status(
            device="cuda", spheres=10, width=8, height=6, frame_ms=1.0, fps=1.0, shading="thesis", rays_per_s=1.5e9
        )
    )
    assert line.endswith("1.0 ms  |  1.0 fps  |  thesis  |  1.5 G rays/s")
    for per_s, text in [(None, "- rays/s"), (12.0, "12 rays/s"), (12345.0, "12.3 k rays/s"), (2.5e8, "250 M rays/s")]:
        status = overlay.Status(
            device="cpu", spheres=1, width=1, height=1, frame_ms=1.0, fps=None, shading="whitted", rays_per_s=per_s
        )
        assert overlay.status_line(status).endswith("whitted  |  " + text)


# --------------------------------------------------------------------------- pacing


def test_handoff_allows_one_frame_in_flight_and_one_waiting():
    handoff = Handoff()
    assert handoff.may_trace()
    handoff.start("request 1")
    assert not handoff.may_trace() and handoff.in_flight == "request 1"
    with pytest.raises(RuntimeError):
        handoff.start("request 2")
    handoff.finish("frame 1")
    assert not handoff.may_trace()  # traced but not yet shown: no new trace
    assert handoff.take() == "frame 1"
    assert handoff.take() is None
    assert handoff.may_trace()


def test_frame_stats_average_over_the_last_second():
    stats = FrameStats()
    assert stats.frame_ms(0.0) is None and stats.fps(0.0) is None
    for i in range(11):  # a frame every 0.1 s, alternating 10 and 30 ms
        stats.add(i * 0.1, 10.0 if i % 2 else 30.0)
    assert stats.fps(1.0) == pytest.approx(10.0)
    assert stats.frame_ms(1.0) == pytest.approx(sum(10.0 if i % 2 else 30.0 for i in range(1, 11)) / 10)


def test_frame_stats_rays_per_second_are_all_rays_over_all_trace_time():
    stats = FrameStats()
    assert stats.rays_per_s(0.0) is None
    stats.add(0.0, 10.0, 1000)
    stats.add(0.5, 30.0, 5000)
    assert stats.rays_per_s(0.6) == pytest.approx(6000 / 0.040)
    assert stats.rays_per_s(1.2) == pytest.approx(5000 / 0.030)  # the first left the last second
    assert stats.rays_per_s(9.0) == pytest.approx(5000 / 0.030)  # none in it: the last frame's
    stats.reset()
    assert stats.rays_per_s(9.0) is None


def test_frame_stats_for_frames_slower_than_a_second():
    stats = FrameStats()
    stats.add(0.0, 2500.0)
    assert stats.fps(0.5) is None  # one frame: no rate yet
    assert stats.frame_ms(3.0) == 2500.0  # older than a second, still the latest news
    stats.add(2.5, 2400.0)
    assert stats.fps(2.6) == pytest.approx(1 / 2.5)
    assert stats.fps(7.5) == pytest.approx(1 / 5.0)  # nothing new for 5 s: the rate decays
    assert stats.frame_ms(7.5) == 2400.0


# --------------------------------------------------------------------------- the tracing thread


def run_worker(requests, timeout=600):
    """Trace requests one after another through a TraceWorker, as the window
    does (submit, wait for on_done, take); the results. timeout: a guard
    against a hang only, so it allows a cold compile on a slow, busy machine
    (over 120 s was seen on CI's 2 cores)."""
    done = threading.Event()
    worker = TraceWorker(on_done=done.set)
    results = []
    try:
        for request in requests:
            done.clear()
            worker.submit(request)
            assert done.wait(timeout), "the worker did not finish in time"
            results.append(worker.handoff.take())
    finally:
        worker.close()
    return results


def request_for(scene, device, count=None, width=24, height=16, camera=None, options=None, number=1):
    return TraceRequest(
        number=number,
        device=device,
        scene=scene,
        count=len(scene) if count is None else count,
        camera=camera or Camera(),
        width=width,
        height=height,
        options=options or {},
    )


def test_worker_frames_are_what_render_draws():
    scene = random_spheres(30, 5)
    camera = Camera(position=(0.5, 0, -1), look_at=(0, 0, 10))
    results = run_worker(
        [
            request_for(scene, "cpu", camera=camera),
            request_for(scene, "cpu", count=12, camera=camera, options={"threads": 3}),
        ]
    )
    assert all(isinstance(r, TracedFrame) for r in results), results
    full, prefix = results
    assert np.array_equal(full.frame.image, raybench.render(scene, camera, 24, 16, device="cpu").image)
    assert full.frame.hits is None  # the window never reads them: none are kept
    assert np.array_equal(prefix.frame.image, raybench.render(scene.head(12), camera, 24, 16, device="cpu").image)
    assert np.array_equal(full.rgba[..., :3], full.frame.image) and (full.rgba[..., 3] == 255).all()
    assert full.compile_s is not None and prefix.compile_s is not None  # new options: a new tracer
    assert full.trace_ms > 0


@pytest.mark.slow
def test_worker_whitted_frames_are_what_render_draws_with_every_ray_counted():
    """Whitted frames through the worker, as the state asks for them (the
    light moved, then a prefix of the spheres): render()'s pictures, hits and
    ray counts, on the CPU (its first Whitted frame compiles for a minute)."""
    scene = lit_file_scene()
    state = ViewerState(scene, device="cpu", seed=None, clock=Clock(), shading=FirstShading("whitted", 2, 2))
    state.camera = Camera(position=(-10, 1, 15), look_at=(0, 0, 15))
    first = state.next_request(24, 16)
    state.handle_event(key("k"))
    state.handle_event(key("-"))
    moved = state.next_request(24, 16)
    assert moved.count == 2 and moved.scene is not scene
    results = run_worker([first, moved], timeout=600)
    assert all(isinstance(r, TracedFrame) for r in results), results
    for request, traced in zip((first, moved), results):
        expected = raybench.render(
            request.scene.head(request.count),
            request.camera,
            24,
            16,
            device="cpu",
            shading="whitted",
            depth=2,
            shadow_samples=2,
        )
        assert np.array_equal(traced.frame.image, expected.image)
        assert traced.frame.hits is None
        assert traced.frame.rays == expected.rays and list(traced.frame.rays) == list(KINDS)
        assert traced.rays_cast == sum(expected.rays.values()) > 24 * 16  # shadow rays at least
    assert not np.array_equal(results[0].frame.image, results[1].frame.image)


def test_whitted_with_a_thesis_only_option_fails_in_the_title_and_g_goes_back():
    """view --accel none --kernel fast, then G: Whitted's brute force has the
    simple kernel only. The worker says so (nothing is compiled), the title
    shows it, and G goes back to frames that trace."""
    state, _ = make_state(n=12, options={"cpu": {"accel": "none", "kernel": "fast"}})
    state.handle_event(key("g"))
    (failed,) = run_worker([state.next_request(8, 6)])
    assert isinstance(failed, TraceFailed) and "kernel 'fast'" in failed.message
    state.on_traced(failed)
    assert state.next_request(8, 6) is None and "kernel 'fast'" in state.title()
    state.handle_event(key("g"))
    request = state.next_request(8, 6)
    assert request.shading is None and request.options == {"accel": "none", "kernel": "fast"}


@pytest.mark.gpu
@pytest.mark.skipif(not cuda_backend.available(), reason="no CUDA GPU and the simulator is off")
def test_worker_switches_cpu_to_cuda_and_back():
    """Real device switch (cuda is numba's simulator without a GPU): each frame
    comes from the device asked for; the pictures agree (bit for bit under the
    simulator, within a step on a real GPU)."""
    scene = random_spheres(8, 1)
    results = run_worker(
        [request_for(scene, d, width=16, height=12, number=i) for i, d in enumerate(["cpu", "cuda", "cpu"])]
    )
    assert [r.frame.device for r in results] == ["cpu", "cuda", "cpu"]
    diff = np.abs(results[0].frame.image.astype(int) - results[1].frame.image.astype(int))
    assert diff.max() <= (0 if cuda_backend.simulated() else 1)


def test_worker_reports_an_unusable_device_and_goes_on(monkeypatch):
    monkeypatch.setattr(cuda_backend.device, "available", lambda: False)
    scene = random_spheres(5, 1)
    failed, traced = run_worker([request_for(scene, "cuda"), request_for(scene, "cpu")])
    assert isinstance(failed, TraceFailed) and "device cuda" in failed.message
    assert isinstance(traced, TracedFrame) and traced.frame.device == "cpu"


def test_worker_traces_off_the_event_loop():
    """While a slow frame is traced, events are handled at once: the tracer runs
    on the worker thread, and the CPU kernel releases the GIL."""
    scene = random_spheres(3000, 0)  # about a second per frame on one thread of a slow machine
    state, _ = make_state()
    done = threading.Event()
    worker = TraceWorker(on_done=done.set)
    try:
        slow = {"accel": "none", "kernel": "simple"}
        worker.submit(request_for(scene, "cpu", width=24, height=16, options=slow))  # compiles before the frame
        assert done.wait(120)
        worker.handoff.take()
        done.clear()
        start = time.perf_counter()
        # the thesis's loop: the BVH and the fast kernel would trace this frame too quickly to tell
        worker.submit(request_for(scene, "cpu", width=400, height=300, options={"threads": 1, **slow}))
        slowest = 0.0
        deadline = time.monotonic() + 300  # a guard against a frame that never ends, not a timing
        while not done.is_set() and time.monotonic() < deadline:
            t = time.perf_counter()
            state.handle_event(key("d"))
            state.handle_event(key("d", "key_up"))
            state.next_request(8, 6)
            slowest = max(slowest, time.perf_counter() - t)
            time.sleep(0.005)
        frame_s = time.perf_counter() - start
        assert done.wait(120)
        result = worker.handoff.take()
    finally:
        worker.close()
    assert isinstance(result, TracedFrame)
    assert frame_s > 0.1, "the frame was too quick to show anything"
    # A kernel that held the GIL would stall an event for about the whole frame; a busy CI
    # machine's scheduler may stall one for some ms. So the bound grows with the frame.
    bound = max(0.05, frame_s / 4)
    assert slowest < bound, f"an event took {slowest * 1e3:.0f} ms while a {frame_s:.2f} s frame was traced"


# ---------------------------------------------------------------- bad input: one line, exit 2, before any window


@pytest.mark.parametrize(
    "args,needles",
    [
        (["--spheres", "3", "--size", "0x5"], ["width", "got 0"]),
        (["--spheres", "3", "--size", "big"], ["--size", "big"]),
        (["--spheres", "3", "--device", "tpu"], ["--device", "tpu"]),
        (["--spheres", "3", "--screenshot", "x.png"], ["--screenshot", "--frames"]),
        (["--spheres", "3", "--frames", "2", "--screenshot", "x.jpg"], ["--screenshot", ".png"]),
        (["--spheres", "3", "--frames", "2", "--screenshot", "missing/x.png"], ["--screenshot", "does not exist"]),
        (["--spheres", "3", "--frames", "0"], ["--frames", "0"]),
        (["--spheres", "3", "--threads", "0"], ["threads", "got 0"]),
        (["--spheres", "3", "--block", "8"], ["--block"]),
        (["--spheres", "3", "--scene", "s.json"], ["--scene", "--spheres"]),
        (["--spheres", "-4"], ["sphere count", "-4"]),
        (["--spheres", "3", "--depth", "2"], ["--depth", "--shading whitted"]),
        (["--spheres", "3", "--shading", "whitted", "--depth", "99"], ["depth", "99"]),
        (["--spheres", "3", "--shading", "whitted", "--shadow-samples", "0"], ["shadow_samples", "got 0"]),
        (["--spheres", "3", "--shading", "phong"], ["--shading", "phong"]),
        (["--spheres", "3", "--shading", "whitted", "--accel", "none", "--kernel", "fast"], ["kernel 'fast'"]),
    ],
    ids=[
        "size-0",
        "size-word",
        "device",
        "screenshot-without-frames",
        "screenshot-jpg",
        "screenshot-folder",
        "frames-0",
        "threads-0",
        "block",
        "scene-and-spheres",
        "negative-spheres",
        "depth-without-whitted",
        "depth-99",
        "shadow-samples-0",
        "shading-unknown",
        "whitted-fast-kernel",
    ],
)
def test_view_bad_input_is_one_line_and_exit_2(capsys, tmp_path, monkeypatch, args, needles):
    # No screen: input that got past the checks would end in "no display", not in these needles.
    monkeypatch.delenv("DISPLAY", raising=False)
    monkeypatch.delenv("WAYLAND_DISPLAY", raising=False)
    monkeypatch.chdir(tmp_path)
    code = run(["view", *args])
    out, err = capsys.readouterr()
    assert code == 2 and "Traceback" not in out + err
    lines = err.splitlines()
    assert len(lines) == 1 and lines[0].startswith("raybench: error: "), err
    for needle in needles:
        assert needle in lines[0], (needle, lines[0])
    assert list(tmp_path.iterdir()) == []


def test_view_cuda_without_gpu_is_refused_before_the_window(capsys, monkeypatch):
    monkeypatch.setattr(cuda_backend.device, "available", lambda: False)
    monkeypatch.delenv("DISPLAY", raising=False)
    monkeypatch.delenv("WAYLAND_DISPLAY", raising=False)
    code = run(["view", "--spheres", "3", "--device", "cuda"])
    err = capsys.readouterr().err
    assert code == 2 and err.startswith("raybench: error: device cuda") and "--device cpu" in err


def test_view_takes_renders_device_options_each_device_its_own(monkeypatch):
    """view's device options are render's, parsed by the same code; the window
    gets each device's share (it switches device live), checked before it opens."""
    opened = []
    monkeypatch.setattr(viewer, "view", lambda state, size, **kw: opened.append(state))
    flags = ["--threads", "2", "--block", "8x8", "--accel", "none", "--kernel", "simple"]
    assert run(["view", "--spheres", "3", "--device", "cpu", *flags]) == 0
    common = {"accel": "none", "kernel": "simple"}
    assert opened[0].options == {
        "cpu": {"threads": 2, **common},
        "cuda": {"block": (8, 8), **common},
        "wgpu": common,
    }
    assert cli.device_options(threads=2, block="8x8", accel="none", kernel="simple") == {
        "threads": 2,
        "block": (8, 8),
        **common,
    }


def test_view_takes_renders_shading_options(monkeypatch):
    opened = []
    monkeypatch.setattr(viewer, "view", lambda state, size, **kw: opened.append(state))
    assert run(["view", "--scene", "whitted", "--shading", "whitted", "--depth", "3", "--shadow-samples", "2"]) == 0
    assert run(["view", "--spheres", "4", "--materials"]) == 0
    whitted_state, thesis_state = opened
    whitted_lit, thesis_lit = whitted_state.lighting, thesis_state.lighting
    assert {k: getattr(whitted_lit, k) for k in ("shading", "depth", "shadow_samples")} == {
        "shading": "whitted",
        "depth": 3,
        "shadow_samples": 2,
    }
    assert len(whitted_state.supply.scene.lights) == 1 and whitted_state.supply.seed is None
    assert (thesis_lit.shading, thesis_lit.depth, thesis_lit.shadow_samples) == ("thesis", None, None)
    assert thesis_state.supply.scene.materials == random_spheres(4, 0, materials=True).materials


def test_view_refuses_options_the_first_device_refuses_before_the_window(capsys, monkeypatch):
    opened = []
    monkeypatch.setattr(viewer, "view", lambda state, size, **kw: opened.append(kw))
    code = run(["view", "--spheres", "3", "--device", "cpu", "--kernel", "fast", "--accel", "bvh"])
    err = capsys.readouterr().err
    assert code == 2 and len(err.splitlines()) == 1
    assert err.startswith("raybench: error: kernel: applies to brute force only")
    assert opened == []


# --------------------------------------------------------------------------- --animate


def test_animate_stamps_each_request_with_the_time_since_the_window_opened():
    state, clock = make_state(animate=True)
    clock.advance(0.25)
    first = state.next_request(32, 20)
    clock.advance(0.5)
    assert (first.time, state.next_request(32, 20).time) == (0.25, 0.75)
    still, _ = make_state()
    assert still.next_request(32, 20).time is None


def test_animated_title_shows_the_update_and_the_trace_apart():
    state, clock = make_state(n=50, animate=True)
    request = state.next_request(320, 200)
    image = np.zeros((200, 320, 3), np.uint8)
    frame = raybench.Frame(image=image, hits=np.full((200, 320), -1, np.int32), device="cuda")
    state.on_traced(TracedFrame(request, frame, to_rgba(image), 4.0, None, update_ms=0.31, update="refit"))
    parts = state.title().split("  |  ")
    assert parts[4:6] == ["refit 0.31 ms", "trace 4.0 ms"], parts


@pytest.mark.parametrize("t", [0.0, 1.7])
def test_worker_moves_the_spheres_to_the_requests_time(t):
    """An animated request: the tree rebuilt (cpu) for the spheres where
    animate.Orbits (seed 0) puts them, and the frame is theirs."""
    from raybench import animate

    scene = random_spheres(30, 5)
    moved = animate.Orbits(scene.spheres, 0).at(t)
    # the reference first, through the same kernels: compiled before the worker's wait starts
    want = raybench.render(raybench.Scene(moved[:3].T, moved[3], moved[4:].T), Camera(), 24, 16, device="cpu")
    request = TraceRequest(number=1, device="cpu", scene=scene, count=30, camera=Camera(), width=24, height=16, time=t)
    (result,) = run_worker([request])
    assert isinstance(result, TracedFrame), result
    assert result.update == "build" and result.update_ms > 0
    assert np.array_equal(result.frame.image, want.image) and result.frame.hits is None
