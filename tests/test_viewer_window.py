"""The viewer's real window, on a virtual screen: Xvfb, and wgpu on a Vulkan
adapter (lavapipe, Mesa's CPU Vulkan driver, where there is no GPU).

What is checked is what was drawn: every picture is read back from the
window's surface after the texture-to-quad pass, and compared with what
`raybench render` (or raybench.render) makes of the same view.

These tests skip when Xvfb or a Vulkan adapter is missing, except where
RAYBENCH_REQUIRE_WINDOW=1 (CI sets it): there a missing piece is a failure.
"""

from __future__ import annotations

import gc
import os
import shutil
import subprocess
import sys
import threading
import time

import numpy as np
import pytest
from PIL import Image

import raybench
from raybench import Camera, Scene, examples, random_spheres
from raybench.backends import cuda as cuda_backend
from raybench.cli import run

REQUIRED = os.environ.get("RAYBENCH_REQUIRE_WINDOW") == "1"

pytestmark = pytest.mark.window


def unavailable(reason: str):
    if REQUIRED:
        pytest.fail(f"{reason}; RAYBENCH_REQUIRE_WINDOW=1 requires the window tests to run")
    pytest.skip(reason)


@pytest.fixture(scope="session")
def vulkan_adapter():
    import wgpu

    from raybench.viewer.gpu import native_stderr_captured

    with native_stderr_captured():
        adapters = wgpu.gpu.enumerate_adapters_sync()
    vulkan = [a for a in adapters if a.info["backend_type"] == "Vulkan"]
    if not vulkan:
        unavailable("no Vulkan adapter for wgpu (on Debian: apt-get install mesa-vulkan-drivers libvulkan1)")
    return vulkan[0]


def start_xvfb() -> tuple[subprocess.Popen, int]:
    """A fresh Xvfb server on the first free display from :91: (its process, the number)."""
    xvfb = shutil.which("Xvfb")
    if xvfb is None:
        unavailable("Xvfb is not installed (on Debian: apt-get install xvfb)")
    for number in range(91, 200):
        if os.path.exists(f"/tmp/.X{number}-lock") or os.path.exists(f"/tmp/.X11-unix/X{number}"):
            continue
        proc = subprocess.Popen(
            [xvfb, f":{number}", "-screen", "0", "1280x1024x24", "-nolisten", "tcp"],
            stdout=subprocess.DEVNULL,
            stderr=subprocess.DEVNULL,
        )
        deadline = time.monotonic() + 10
        while proc.poll() is None and not os.path.exists(f"/tmp/.X11-unix/X{number}") and time.monotonic() < deadline:
            time.sleep(0.05)
        if proc.poll() is None and os.path.exists(f"/tmp/.X11-unix/X{number}"):
            break
        proc.kill()
        proc.wait()
    else:
        pytest.fail("Xvfb did not start on any display from :91 to :199")
    return proc, number


@pytest.fixture(scope="session")
def display(vulkan_adapter):
    """A fresh Xvfb server for this session; DISPLAY points at it meanwhile."""
    proc, number = start_xvfb()
    previous = os.environ.get("DISPLAY")
    os.environ["DISPLAY"] = f":{number}"
    try:
        yield f":{number}"
    finally:
        # Windows the tests left for the garbage collector release their
        # surfaces now, before glfw ends (releasing one after can crash).
        gc.collect()
        if "glfw" in sys.modules:
            # Close this process's X connection before the server goes: Xlib ends
            # a process whose server vanishes under it ("XIO: fatal IO error").
            import glfw

            glfw.terminate()
            glfw._rc_alive = False  # rendercanvas's flag: glfw may not be polled any more
        if previous is None:
            os.environ.pop("DISPLAY", None)
        else:
            os.environ["DISPLAY"] = previous
        proc.terminate()
        try:
            proc.wait(5)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait()


def read_png(path) -> np.ndarray:
    with Image.open(path) as img:
        assert img.format == "PNG" and img.mode == "RGB"
        return np.asarray(img)


def render_png(tmp_path, name, *args) -> np.ndarray:
    """`raybench render ARGS -o tmp_path/name`, in this process; its pixels."""
    out = tmp_path / name
    assert run(["render", *map(str, args), "-o", str(out)]) == 0
    return read_png(out)


def reference(traced) -> np.ndarray:
    """What raybench.render draws for the request a traced frame was made for."""
    r = traced.request
    return raybench.render(r.scene.head(r.count), r.camera, r.width, r.height, device="cpu").image


# --------------------------------------------------------------------------- driving a window in this process


def key(name, kind="key_down"):
    return {"event_type": kind, "key": name, "modifiers": ()}


def press(*names):
    """An action that presses (and releases) keys through the viewer's event handler."""

    def action(window):
        for name in names:
            window.handle_event(key(name))
            window.handle_event(key(name, "key_up"))

    return action


def nothing(window):
    pass


def first_frame(traced):
    return True


class Script:
    """Steps to play on an open window, each (action, until): action(window)
    runs inside a draw, right after a traced frame is drawn; then every frame
    traced *after* the action is recorded, with what the window drew for it,
    until until(traced) is true. Then the next step; after the last, the
    window closes."""

    def __init__(self, steps):
        self.steps = list(steps)
        self.records = []  # (step index, traced frame, pixels drawn)
        self.step = -1
        self.after = 0  # requests up to this number came before the step's action
        self.until = first_frame

    def __call__(self, window, traced):
        if traced.request.number <= self.after:
            return
        if self.step >= 0:
            self.records.append((self.step, traced, window.read_drawn()))
            if not self.until(traced):
                return
        self.step += 1
        if self.step == len(self.steps):
            window.close()
            return
        action, self.until = self.steps[self.step]
        action(window)
        self.after = window.state.requests_made

    def frames(self, step):
        return [(traced, pixels) for s, traced, pixels in self.records if s == step]


def play(state, size, steps, timeout=600, prepare=None):
    """Open a real window on state, play the steps, close; the Script."""
    from raybench.viewer.window import ViewerWindow

    window = ViewerWindow(state, size)
    if prepare:
        prepare(window)
    script = Script([(nothing, first_frame)] + list(steps))
    window.add_frame_listener(script)
    timed_out = threading.Event()

    def stop():
        timed_out.set()
        window.loop.call_soon_threadsafe(window.close)

    watchdog = threading.Timer(timeout, stop)
    watchdog.start()
    try:
        window.run()
    finally:
        watchdog.cancel()
    assert not timed_out.is_set(), f"the window was still at step {script.step} after {timeout} s"
    assert script.step == len(script.steps), f"the window closed at step {script.step}"
    return script, window


def state_for(scene, seed, device="cpu", **kwargs):
    from raybench.viewer.state import ViewerState

    return ViewerState(scene, device=device, seed=seed, **kwargs)


# --------------------------------------------------------------------------- the picture is the render


@pytest.mark.slow
def test_screenshot_equals_raybench_render(display, tmp_path):
    """The CLI end to end: `raybench view --frames 3 --screenshot` saves what the
    window drew, and it is `raybench render` of the same view, byte for byte."""
    env = dict(os.environ, DISPLAY=display)
    args = ["--spheres", "20", "--size", "160x120", "--device", "cpu"]
    shot = tmp_path / "view.png"
    proc = subprocess.run(
        [sys.executable, "-m", "raybench", "view", *args, "--frames", "3", "--screenshot", shot],
        cwd=tmp_path,
        env=env,
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert proc.returncode == 0, proc.stderr
    assert "Traceback" not in proc.stdout + proc.stderr
    assert f"wrote {shot}: 160x120, 20 spheres, cpu" in proc.stdout
    rendered = subprocess.run(
        [sys.executable, "-m", "raybench", "render", *args, "-o", tmp_path / "render.png"],
        cwd=tmp_path,
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert rendered.returncode == 0, rendered.stderr
    drawn, expected = read_png(shot), read_png(tmp_path / "render.png")
    assert drawn.shape == expected.shape == (120, 160, 3)
    assert np.array_equal(drawn, expected)
    assert len(np.unique(drawn.reshape(-1, 3), axis=0)) > 100  # a real picture, not a blank window


@pytest.mark.slow
def test_screenshot_equals_raybench_render_under_whitted_shading(display, tmp_path):
    """`raybench view --shading whitted --frames 2 --screenshot` on the CPU: the
    window drew `raybench render --shading whitted`, byte for byte. (Small:
    the first Whitted frame of each process compiles for about a minute.)"""
    env = dict(os.environ, DISPLAY=display)
    shading = ["--shading", "whitted", "--depth", "3", "--shadow-samples", "2"]
    args = ["--scene", "whitted", "--size", "64x48", "--device", "cpu", *shading]
    shot = tmp_path / "view.png"
    proc = subprocess.run(
        [sys.executable, "-m", "raybench", "view", *args, "--frames", "2", "--screenshot", shot],
        cwd=tmp_path,
        env=env,
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert proc.returncode == 0, proc.stderr
    assert "Traceback" not in proc.stdout + proc.stderr
    assert f"wrote {shot}: 64x48, 7 spheres, cpu, whitted" in proc.stdout
    drawn = read_png(shot)
    assert np.array_equal(drawn, render_png(tmp_path, "render.png", *args))
    thesis = render_png(tmp_path, "thesis.png", *args[:6])
    assert not np.array_equal(drawn, thesis)  # lit: not the thesis's picture


def test_frames_without_screenshot_shows_n_frames_and_exits(display, capsys, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    code = run(["view", "--spheres", "5", "--size", "40x30", "--device", "cpu", "--frames", "4"])
    out, err = capsys.readouterr()
    assert code == 0, err
    assert out.startswith("showed 4 frames; the last: 40x30, 5 spheres, cpu")
    assert list(tmp_path.iterdir()) == []


def test_a_mesh_file_in_the_window_equals_raybench_render(display, capsys, tmp_path, monkeypatch):
    """`raybench view --scene box.obj`: the mesh from the camera fitted to
    it, what `raybench render` draws of it (both in this process: the cpu's
    triangle kernels, not in the disk cache, compile once)."""
    import trimesh

    monkeypatch.chdir(tmp_path)
    trimesh.creation.box(extents=(2.0, 1.0, 1.0)).export(tmp_path / "box.obj")
    args = ["--scene", "box.obj", "--size", "40x30", "--device", "cpu"]
    code = run(["view", *args, "--frames", "1", "--screenshot", "view.png"])
    out, err = capsys.readouterr()
    assert code == 0, err
    assert "40x30, 12 triangles, cpu" in out
    assert np.array_equal(read_png(tmp_path / "view.png"), render_png(tmp_path, "render.png", *args))


def test_scene_file_camera_in_the_window_equals_raybench_render(display, tmp_path):
    """A scene file with its own camera, in a window of an odd size."""
    spheres = random_spheres(25, 8)
    path = tmp_path / "scene.json"
    Scene(
        spheres.centers, spheres.radii, spheres.colors, Camera(position=(1, 0.5, -2), look_at=(0, 0, 12), fov_deg=48)
    ).save(path)
    script, _ = play(state_for(Scene.load(path), None), (97, 61), [])
    ((traced, drawn),) = script.frames(0)
    assert (traced.frame.width, traced.frame.height) == (97, 61)
    assert np.array_equal(drawn, render_png(tmp_path, "r.png", "--scene", path, "--size", "97x61", "--device", "cpu"))


def test_keys_change_what_is_drawn(display, tmp_path):
    """+, -, the ramp, WASD and R, pressed through the viewer's event handler:
    each changes the picture as it should, and every picture drawn is what
    raybench.render makes of the frame's own view."""

    def held(name, seconds):
        def action(window):
            window.handle_event(key(name))
            time.sleep(seconds)
            window.handle_event(key(name, "key_up"))

        return action

    steps = [
        (press("="), first_frame),  # 1: 30 spheres
        (press("-", "-"), first_frame),  # 2: 10 of those
        (press("t"), lambda t: t.request.count >= 40),  # 3: the ramp
        (press("t"), first_frame),  # 4: stopped
        (held("w", 0.3), first_frame),  # 5: moved forward
        (press("r"), first_frame),  # 6: back home
    ]
    script, window = play(state_for(random_spheres(20, 0), 0), (64, 48), steps)
    for step, traced, drawn in script.records:
        assert np.array_equal(drawn, reference(traced)), f"step {step}, frame {traced.request.number}"
    ((start, start_px),) = script.frames(0)
    assert start.request.count == 20
    assert np.array_equal(
        start_px, render_png(tmp_path, "20.png", "--spheres", 20, "--size", "64x48", "--device", "cpu")
    )
    ((more, more_px),) = script.frames(1)
    assert more.request.count == 30 and not np.array_equal(more_px, start_px)
    assert np.array_equal(
        more_px, render_png(tmp_path, "30.png", "--spheres", 30, "--size", "64x48", "--device", "cpu")
    )
    ((fewer, fewer_px),) = script.frames(2)
    assert fewer.request.count == 10 and not np.array_equal(fewer_px, more_px)
    ramp = script.frames(3)
    assert [t.request.count for t, _ in ramp] == [10, 20, 30, 40]
    assert all(len(t.request.scene) == 1000 for t, _ in ramp)  # test 7's scene
    assert all(not np.array_equal(a, b) for (_, a), (_, b) in zip(ramp, ramp[1:]))
    ((stopped, _),) = script.frames(4)
    assert stopped.request.count in (40, 50) and not window.state.supply.ramping
    ((moved, moved_px),) = script.frames(5)
    assert moved.request.camera.position[2] > 0 and not np.array_equal(moved_px, script.frames(4)[0][1])
    ((home, home_px),) = script.frames(6)
    assert home.request.camera is window.state.home
    assert np.array_equal(home_px, script.frames(4)[0][1])


@pytest.mark.slow
@pytest.mark.gpu
@pytest.mark.skipif(not cuda_backend.available(), reason="no CUDA GPU and numba's simulator is off")
def test_tab_switches_live_to_cuda_or_its_simulator_and_draws_the_same_picture(display):
    """Tab traces the next frames on cuda (numba's simulator where there is no
    GPU), then back on the CPU. The algorithm is the same, so the picture is the
    same (bit for bit under the simulator, within a step on a GPU); what changes
    is which device made it, and the title says so."""
    titles = []

    def title_after(window):
        titles.append(window.state.title())

    steps = [(press("Tab"), first_frame), (title_after, first_frame), (press("Tab"), first_frame)]
    script, _ = play(state_for(random_spheres(12, 3), 3), (48, 36), steps, timeout=600)
    devices = [(step, traced.frame.device) for step, traced, _ in script.records]
    assert devices == [(0, "cpu"), (1, "cuda"), (2, "cuda"), (3, "cpu")]
    cpu_px, cuda_px = script.frames(0)[0][1], script.frames(1)[0][1]
    tolerance = 0 if cuda_backend.simulated() else 1
    assert np.abs(cpu_px.astype(int) - cuda_px.astype(int)).max() <= tolerance
    assert "cuda" in titles[0].split("  |  ")[1]


def test_switching_to_cuda_where_there_is_none_stays_on_the_cpu(display, monkeypatch):
    monkeypatch.setattr(cuda_backend.device, "available", lambda: False)
    titles = []
    steps = [(press("Tab"), first_frame), (lambda w: titles.append(w.state.title()), first_frame)]
    script, window = play(state_for(random_spheres(5, 1), 1), (40, 30), steps)
    # The first frame, the cuda frame that failed (nothing to draw), and the next, on the CPU again.
    assert [traced.frame.device for _, traced, _ in script.records] == ["cpu", "cpu", "cpu"]
    assert window.state.device == "cpu"
    assert "device cuda" in titles[0] and "staying on cpu" in titles[0]


def test_resizing_the_window_retraces_at_the_new_size(display):
    def resize(window):
        window.canvas.set_logical_size(90, 70)

    script, _ = play(
        state_for(random_spheres(15, 2), 2), (64, 48), [(resize, lambda t: (t.frame.width, t.frame.height) == (90, 70))]
    )
    traced, drawn = script.frames(1)[-1]
    assert drawn.shape == (70, 90, 3)
    assert np.array_equal(drawn, reference(traced))


def test_screenshot_key_saves_what_was_drawn(display, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    script, window = play(state_for(random_spheres(10, 4), 4), (64, 48), [(press("p"), first_frame)])
    assert len(window.saved) == 1 and window.saved[0].parent == tmp_path
    assert window.saved[0].name.startswith("raybench-view-")
    assert np.array_equal(read_png(window.saved[0]), script.frames(0)[0][1])


def test_screenshot_from_the_offscreen_path(display):
    """Where a surface cannot be copied from, the screenshot is the same quad
    drawn into an offscreen texture of the same format: it must be the same bytes."""

    def offscreen(window):
        window.surface_readable = False

    script, window = play(state_for(random_spheres(10, 6), 6), (64, 48), [], prepare=offscreen)
    ((traced, drawn),) = script.frames(0)
    assert np.array_equal(drawn, reference(traced))


@pytest.mark.slow
def test_keyboard_through_the_x_server(display, tmp_path):
    """One end-to-end run with real key presses (xdotool): the title bar
    reports the frame, + adds spheres, P saves a screenshot, Esc quits."""
    xdotool = shutil.which("xdotool")
    if xdotool is None:
        unavailable("xdotool is not installed (on Debian: apt-get install xdotool)")
    env = dict(os.environ, DISPLAY=display)
    proc = subprocess.Popen(
        [sys.executable, "-m", "raybench", "view", "--spheres", "20", "--size", "160x120", "--device", "cpu"],
        cwd=tmp_path,
        env=env,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )

    def xdo(*args):
        return subprocess.run([xdotool, *args], env=env, capture_output=True, text=True, timeout=30).stdout.strip()

    def wait_for(predicate, what, timeout=60):
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            value = predicate()
            if value:
                return value
            assert proc.poll() is None, f"the viewer exited while waiting for {what}: {proc.communicate()}"
            time.sleep(0.1)
        raise AssertionError(f"timed out waiting for {what}")

    try:
        window_id = wait_for(lambda: xdo("search", "--name", "^raybench").split("\n")[0], "the window")

        def title_with_a_frame():
            title = xdo("getwindowname", window_id)
            return title if "fps" in title else None

        title = wait_for(title_with_a_frame, "a frame in the title")
        assert "cpu" in title and "20 spheres" in title and "160x120" in title and " ms" in title, title
        xdo("windowfocus", "--sync", window_id)
        xdo("key", "--clearmodifiers", "plus")
        wait_for(lambda: "30 spheres" in xdo("getwindowname", window_id), "30 spheres in the title")
        xdo("key", "p")
        shot = wait_for(lambda: next(tmp_path.glob("raybench-view-*.png"), None), "the screenshot")
        xdo("key", "Escape")
        out, err = proc.communicate(timeout=30)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.communicate()
    assert proc.returncode == 0, err
    assert "Traceback" not in out + err
    expected = raybench.render(random_spheres(30, 0), width=160, height=120, device="cpu").image
    assert np.array_equal(read_png(shot), expected)


# --------------------------------------------------------------------------- wgpu: traced into the window's texture


@pytest.mark.gpu
def test_wgpu_traces_into_the_drawn_texture_in_one_command_buffer(display, vulkan_adapter, monkeypatch):
    """The thesis's pipeline: on wgpu, the compute pass writes the texture the
    quad draws, both recorded into one command encoder, and nothing is
    uploaded; the worker thread, not the window's loop, waits for the GPU;
    the picture is the CPU's. Tab leaves wgpu for the CPU (uploaded
    frames again), 3 comes back."""
    from raybench.viewer.gpu import TextureQuad
    from raybench.viewer.zero_copy import InWindowTracer

    encoders = {"compute": [], "quad": [], "uploads": 0}
    real_encode, real_quad, real_upload = InWindowTracer.encode, TextureQuad.encode, TextureQuad.upload

    def compute_encode(self, encoder, request):
        encoders["compute"].append((request.number, id(encoder)))
        return real_encode(self, encoder, request)

    def quad_encode(self, encoder, view):
        encoders["quad"].append(id(encoder))
        return real_quad(self, encoder, view)

    def upload(self, rgba):
        encoders["uploads"] += 1
        return real_upload(self, rgba)

    waited_on = set()
    real_elapsed = InWindowTracer.elapsed_ms

    def elapsed_ms(self):
        waited_on.add(threading.current_thread().name)
        return real_elapsed(self)

    monkeypatch.setattr(InWindowTracer, "elapsed_ms", elapsed_ms)
    monkeypatch.setattr(InWindowTracer, "encode", compute_encode)
    monkeypatch.setattr(TextureQuad, "encode", quad_encode)
    monkeypatch.setattr(TextureQuad, "upload", upload)
    titles = []
    seen = {}

    def check_zero_copy(window):
        seen["same_texture"] = window.quad.texture is window.gpu_tracer.compute.texture
        seen["accel"] = window.gpu_tracer.compute.accel  # the backend's default, as in raybench render
        seen["uploads"] = encoders["uploads"]
        titles.append(window.state.title())

    name = vulkan_adapter.info["device"]
    state = state_for(random_spheres(20, 5), 5, device="wgpu", options={"wgpu": {"adapter": name}})

    def resize(window):
        window.canvas.set_logical_size(50, 34)

    steps = [
        (check_zero_copy, first_frame),
        (press("="), first_frame),
        (press("Tab"), first_frame),
        (press("3"), first_frame),
        (resize, lambda t: (t.frame.width, t.frame.height) == (50, 34)),
    ]
    script, window = play(state, (72, 40), steps)
    assert seen == {"same_texture": True, "uploads": 0, "accel": "bvh"}
    assert f"wgpu on {name} (Vulkan" in titles[0] and "no copy" in titles[0], titles
    devices = [(step, traced.frame.device) for step, traced, _ in script.records if step < 5]
    assert devices == [(0, "wgpu"), (1, "wgpu"), (2, "wgpu"), (3, "cpu"), (4, "wgpu")], devices
    resized, drawn = script.frames(5)[-1]  # a new size: a new texture, drawn as it is
    assert resized.frame.device == "wgpu" and drawn.shape == (34, 50, 3)
    assert np.abs(drawn.astype(int) - reference(resized).astype(int)).max() <= 1
    assert encoders["uploads"] == 1  # the cpu frame's, and only it
    assert waited_on == {"raybench-trace"}  # the worker thread waits for the GPU, never the window's loop
    for step, traced, drawn in script.records:
        expected = reference(traced)
        # A frame traced just before the resize is shown stretched to the new size: compare it unstretched only.
        if drawn.shape == expected.shape or step < 5:
            assert np.abs(drawn.astype(int) - expected.astype(int)).max() <= 1, f"step {step}"
        if traced.frame.device == "wgpu":
            assert traced.rgba is None
            # the frame's compute pass was recorded into the encoder its quad was drawn from
            (encoder,) = [e for number, e in encoders["compute"] if number == traced.request.number]
            assert encoder in encoders["quad"]
    assert script.frames(2)[0][0].request.count == 30


@pytest.mark.gpu
def test_wgpu_in_the_window_without_timestamps(display, vulkan_adapter):
    """Where the device has no timestamp queries, the frame time is the wall
    time of the completed submission; the picture is the same."""

    def no_timestamps(window):
        window.gpu_tracer.period_ns = None

    state = state_for(
        random_spheres(15, 9), 9, device="wgpu", options={"wgpu": {"adapter": vulkan_adapter.info["device"]}}
    )
    script, _ = play(state, (48, 32), [(press("="), first_frame)], prepare=no_timestamps)
    for step, traced, drawn in script.records:
        assert traced.frame.device == "wgpu" and traced.trace_ms > 0
        assert np.abs(drawn.astype(int) - reference(traced).astype(int)).max() <= 1, f"step {step}"


def whitted_reference(traced, adapter):
    """What raybench.render draws on wgpu (the same adapter) for a Whitted frame's request."""
    r = traced.request
    shading = r.shading
    return raybench.render(
        r.scene.head(r.count),
        r.camera,
        r.width,
        r.height,
        device="wgpu",
        adapter=adapter,
        shading="whitted",
        depth=shading.depth,
        shadow_samples=shading.shadow_samples,
    )


@pytest.mark.gpu
def test_whitted_keys_on_wgpu_in_the_window(display, vulkan_adapter):
    """In the window's own texture (wgpu, no copy): G toggles Whitted shading,
    I moves the light up, G goes back. Every Whitted frame drawn is what
    raybench.render draws on the same adapter, with the same rays counted,
    and the title shows the rays per second, every kind counted."""
    from raybench.viewer.shading import FirstShading

    name = vulkan_adapter.info["device"]
    scene = Scene.load(examples.path("whitted"))
    state = state_for(
        scene, None, device="wgpu", options={"wgpu": {"adapter": name}}, shading=FirstShading(depth=2, shadow_samples=2)
    )
    titles = []

    def title(window):
        titles.append((window.state.title(), window.state.shown))

    steps = [
        (press("g"), first_frame),  # 1: whitted
        (title, first_frame),  # 2: the same again, its title
        (press("i"), first_frame),  # 3: the light moved up
        (press("g"), first_frame),  # 4: the thesis's shading again
    ]
    script, window = play(state, (64, 48), steps, timeout=300)
    shaded = [(step, traced.request.shading is not None) for step, traced, _ in script.records]
    assert shaded == [(0, False), (1, True), (2, True), (3, True), (4, False)], shaded
    for step, traced, drawn in script.records:
        assert traced.frame.device == "wgpu" and traced.rgba is None
        if traced.request.shading is None:
            assert np.abs(drawn.astype(int) - reference(traced).astype(int)).max() <= 1, f"step {step}"
            continue
        expected = whitted_reference(traced, name)
        assert np.array_equal(drawn, expected.image), f"step {step}"
        assert traced.frame.rays == expected.rays, f"step {step}"
        assert expected.rays["shadow"] > 0 and expected.rays["reflection"] > 0 and expected.rays["refraction"] > 0
    thesis_px, whitted_px = script.frames(0)[0][1], script.frames(1)[0][1]
    moved, moved_px = script.frames(3)[0]
    assert not np.array_equal(thesis_px, whitted_px) and not np.array_equal(moved_px, whitted_px)
    assert moved.request.scene.lights[0].position[1] > scene.lights[0].position[1]
    assert np.array_equal(script.frames(4)[0][1], thesis_px)
    (text, shown), *_ = titles
    parts = text.split("  |  ")
    assert "wgpu" in parts[1] and parts[6] == "whitted, depth 2, 2 shadow samples", text
    value, unit = parts[7].split(" ", 1)
    assert unit in ("rays/s", "k rays/s", "M rays/s", "G rays/s") and float(value) > 0, text
    # the rays counted in the window's pass, read back: more than one a pixel
    assert shown.rays_cast == sum(shown.frame.rays.values()) > 64 * 48


@pytest.mark.gpu
def test_whitted_without_lights_on_wgpu_is_the_thesis_picture(display, vulkan_adapter):
    """A scene without lights toggled to Whitted shading is traced, and with
    nothing lit (no mirrors, no glass) it is the thesis's picture, by design;
    the light keys say there is no light to move."""
    name = vulkan_adapter.info["device"]
    titles = []
    steps = [
        (press("g"), first_frame),
        (press("j"), first_frame),
        (lambda w: titles.append(w.state.title()), first_frame),
    ]
    state = state_for(random_spheres(15, 9), 9, device="wgpu", options={"wgpu": {"adapter": name}})
    script, _ = play(state, (48, 32), steps, timeout=300)
    (thesis, thesis_px), (whitted, whitted_px) = script.frames(0)[0], script.frames(1)[0]
    assert thesis.request.shading is None and whitted.request.shading is not None
    assert whitted.frame.rays == {"primary": 48 * 32, "shadow": 0, "reflection": 0, "refraction": 0}
    assert np.array_equal(whitted_px, thesis_px)
    assert "no lights" in titles[0]


@pytest.mark.slow
@pytest.mark.gpu
def test_cli_view_on_wgpu_saves_the_render(display, vulkan_adapter, tmp_path):
    """`raybench view --device wgpu --adapter NAME --frames 3 --screenshot`
    saves what the window drew from its own texture: `raybench render`'s PNG."""
    env = dict(os.environ, DISPLAY=display)
    args = ["--spheres", "20", "--size", "96x64"]
    shot = tmp_path / "view.png"
    proc = subprocess.run(
        [
            sys.executable,
            "-m",
            "raybench",
            "view",
            *args,
            "--device",
            "wgpu",
            "--adapter",
            vulkan_adapter.info["device"],
            "--workgroup",
            "8x8",
            "--frames",
            "3",
            "--screenshot",
            shot,
        ],
        cwd=tmp_path,
        env=env,
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert proc.returncode == 0, proc.stderr
    assert f"wrote {shot}: 96x64, 20 spheres, wgpu" in proc.stdout
    drawn = read_png(shot).astype(int)
    expected = render_png(tmp_path, "render.png", *args, "--device", "cpu").astype(int)
    assert drawn.shape == expected.shape and np.abs(drawn - expected).max() <= 1


@pytest.mark.gpu
def test_wgpu_on_an_unnamed_cpu_adapter_is_refused_in_one_line(display, vulkan_adapter, tmp_path):
    from raybench.backends.wgpu import adapters

    if adapters.gpu_present():
        pytest.skip("this machine has a GPU adapter: wgpu needs no name here")
    titles = []
    steps = [(press("3"), first_frame), (lambda w: titles.append(w.state.title()), first_frame)]
    script, window = play(state_for(random_spheres(5, 1), 1), (40, 30), steps)
    assert [traced.frame.device for _, traced, _ in script.records] == ["cpu", "cpu", "cpu"]
    assert window.state.device == "cpu" and window.gpu_tracer is None
    assert "not a GPU" in titles[0] and "--adapter" in titles[0] and "staying on cpu" in titles[0], titles
    env = dict(os.environ, DISPLAY=display)
    assert_one_error_line(view_subprocess(tmp_path, env, "--device", "wgpu"), "no GPU adapter", "--adapter")


# --------------------------------------------------------------------------- the texture-to-quad pipeline alone


@pytest.mark.gpu
def test_quad_copies_every_byte_for_both_target_formats(vulkan_adapter):
    from raybench.viewer.gpu import TextureQuad
    from raybench.viewer.worker import to_rgba

    device = vulkan_adapter.request_device_sync()
    image = np.random.default_rng(1).integers(0, 256, (37, 53, 3), dtype=np.uint8)  # every byte value, odd size
    for fmt in ("bgra8unorm", "rgba8unorm"):
        quad = TextureQuad(device, fmt)
        quad.upload(to_rgba(image))
        assert np.array_equal(quad.draw_offscreen(53, 37), image), fmt
        stretched = quad.draw_offscreen(106, 74)  # a frame from before a resize: nearest texel, no blending
        assert np.array_equal(stretched[::2, ::2], image) and np.array_equal(stretched[1::2, 1::2], image), fmt


@pytest.mark.gpu
def test_an_srgb_target_would_change_the_bytes(vulkan_adapter):
    """Why the target is drawn through a non-sRGB view: an sRGB target encodes
    what the pixel shader writes, and a byte of 128 lands as 188."""
    from raybench.viewer.gpu import TextureQuad
    from raybench.viewer.worker import to_rgba

    device = vulkan_adapter.request_device_sync()
    quad = TextureQuad(device, "rgba8unorm-srgb")
    quad.upload(to_rgba(np.full((4, 6, 3), 128, np.uint8)))
    assert (quad.draw_offscreen(6, 4) == 188).all()


def test_srgb_only_surface_is_drawn_through_its_plain_view(display, monkeypatch):
    """A surface that offers only an sRGB format (many do): the window
    configures it with its non-sRGB twin as view format and draws through that
    view, so what is read back from the surface is still the render's bytes."""
    from raybench.viewer import window as window_module

    real = window_module.surface_capabilities

    def srgb_only(context, adapter):
        caps = real(context, adapter)
        assert "bgra8unorm-srgb" in caps["formats"], caps
        return {**caps, "formats": ["bgra8unorm-srgb"]}

    monkeypatch.setattr(window_module, "surface_capabilities", srgb_only)
    script, window = play(state_for(random_spheres(10, 7), 7), (64, 48), [])
    assert (window.format.configure, window.format.view) == ("bgra8unorm-srgb", "bgra8unorm")
    assert window.surface_readable
    ((traced, drawn),) = script.frames(0)
    assert np.array_equal(drawn, reference(traced))


def test_target_format_choice():
    from raybench.errors import RaybenchError
    from raybench.viewer.gpu import choose_target_format

    assert choose_target_format(["bgra8unorm-srgb", "bgra8unorm"]).view == "bgra8unorm"
    assert choose_target_format(["rgba16float", "rgba8unorm"]).configure == "rgba8unorm"
    srgb = choose_target_format(["bgra8unorm-srgb"])
    assert (srgb.configure, srgb.view, srgb.view_formats) == ("bgra8unorm-srgb", "bgra8unorm", ["bgra8unorm"])
    with pytest.raises(RaybenchError, match="raybench render"):
        choose_target_format(["rgba16float"])


# --------------------------------------------------------------------------- no screen, no adapter, bad input


def assert_one_error_line(proc, *needles):
    assert proc.returncode == 2, (proc.returncode, proc.stdout, proc.stderr)
    assert "Traceback" not in proc.stdout + proc.stderr
    lines = proc.stderr.splitlines()
    assert len(lines) == 1 and lines[0].startswith("raybench: error: "), proc.stderr
    for needle in needles:
        assert needle in lines[0], (needle, lines[0])


def view_subprocess(tmp_path, env, *args):
    return subprocess.run(
        [sys.executable, "-m", "raybench", "view", "--spheres", "5", "--size", "40x30", "--device", "cpu", *args],
        cwd=tmp_path,
        env=env,
        capture_output=True,
        text=True,
        timeout=600,
    )


def test_no_display_is_one_line_and_exit_2(tmp_path):
    env = {k: v for k, v in os.environ.items() if k not in ("DISPLAY", "WAYLAND_DISPLAY")}
    assert_one_error_line(view_subprocess(tmp_path, env), "no display", "raybench render")
    assert list(tmp_path.iterdir()) == []


def test_unreachable_display_is_one_line_and_exit_2(tmp_path):
    env = dict(os.environ, DISPLAY=":4097")
    env.pop("WAYLAND_DISPLAY", None)
    assert_one_error_line(view_subprocess(tmp_path, env), "no display", ":4097", "raybench render")


def test_no_graphics_adapter_is_one_line_and_exit_2(display, tmp_path):
    # D3D12 does not exist on Linux: wgpu is asked for an adapter it cannot have.
    if not sys.platform.startswith("linux"):
        pytest.skip("D3D12 stands for 'no adapter' on Linux only")
    env = dict(os.environ, DISPLAY=display, WGPU_BACKEND_TYPE="D3D12")
    assert_one_error_line(
        view_subprocess(tmp_path, env, "--frames", "1", "--screenshot", tmp_path / "x.png"),
        "no usable graphics adapter",
        "raybench render",
    )
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("device", ["cpu", "wgpu"])
def test_animate_moves_the_spheres_in_the_window(display, vulkan_adapter, device):
    """--animate through the window: every frame the tree is rebuilt for the
    moved spheres (cpu through the worker; wgpu in the window's own pass),
    and the title names the update and the trace apart."""
    from raybench.viewer import view

    options = {"wgpu": {"adapter": vulkan_adapter.info["device"]}} if device == "wgpu" else {}
    state = state_for(random_spheres(20, 3), 3, device=device, options=options, animate=True)
    window = view(state, (40, 30), frames=3)
    shown = window.state.shown
    assert shown.update == "build" and shown.update_ms > 0 and shown.request.time > 0
    parts = window.state.title().split("  |  ")
    assert parts[4].startswith("build ") and parts[5].startswith("trace "), parts


def test_cli_view_animate_shows_its_frames(display, capsys, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    code = run(["view", "--spheres", "5", "--size", "40x30", "--device", "cpu", "--animate", "--frames", "3"])
    out, err = capsys.readouterr()
    assert code == 0, err
    assert out.startswith("showed 3 frames; the last: 40x30, 5 spheres, cpu")


def test_losing_the_display_is_one_line_and_exit_2(vulkan_adapter, tmp_path):
    """The X server killed under an open window: one line of raybench's and exit
    2, where Xlib alone prints its own two and exits 1."""
    xvfb, number = start_xvfb()
    runtime = tmp_path / "runtime"
    runtime.mkdir(mode=0o700)
    env = dict(os.environ, DISPLAY=f":{number}", XDG_RUNTIME_DIR=str(runtime))
    view = subprocess.Popen(
        [sys.executable, "-m", "raybench", "view", "--spheres", "20", "--size", "96x64", "--device", "cpu"]
        + ["--frames", "100000000"],
        cwd=tmp_path,
        env=env,
        stdout=subprocess.DEVNULL,
        stderr=subprocess.PIPE,
        text=True,
    )
    try:
        # the title names the spheres once the window draws, its setup done: the server killed
        # during the setup met the Vulkan driver first, whose error wgpu-native aborts on
        shown = subprocess.run(
            ["xdotool", "search", "--sync", "--name", "spheres"], env=env, capture_output=True, timeout=240
        )
        assert shown.returncode == 0 and view.poll() is None, shown
        xvfb.kill()
        xvfb.wait()
        err = view.communicate(timeout=60)[1]
    finally:
        view.kill()
        xvfb.kill()
    assert view.returncode == 2, err
    assert err.splitlines() == [
        f"raybench: error: the window's display :{number} was lost (its X server closed the connection)"
    ], err
