"""The viewer's frames a second, headless: `raybench view`'s own per-frame work, with no window.

Each frame goes the window's way (raybench.viewer.drawing.FrameDrawer, the very steps the window
runs at each draw), drawn into an offscreen texture of the window's format instead of the
surface's:
- cpu and cuda: the viewer's TraceWorker thread traces the frame through a Renderer while the
  previous one is drawn; the draw hands the finished frame to the ViewerState, uploads it to the
  TextureQuad's texture and draws the quad; then the next frame goes to the worker;
- wgpu: the draw records the frame's compute pass into the texture the quad draws (zero_copy, no
  copy) and the quad's pass in one command buffer; the worker thread waits for the GPU; the
  next draw counts the frame and shows it again, and the one after records the next pass.

Left out, and only that: the swap chain's present (no vsync, no compositor) and the canvas's own
scheduling. The window asks for a draw exactly where this loop draws (a frame ready, or wgpu's
next pass to record), but rendercanvas draws at most MAX_FPS times a second (viewer.window), so
the window itself shows at most MAX_FPS / draws_per_frame frames a second: each record gives
that cap (window_cap_fps) beside what the work allows.

The camera orbits (camera_path.orbit: the viewer's home camera about the middle of the spheres,
a full turn over a point's frames, --orbit to change), so that every frame is new work, as a
user turning the view makes it; --animate also moves the spheres as `raybench view --animate`
does (the tree refit or rebuilt each frame). The scene is the issue's: random_spheres(n,
materials=True), lit by its area light; or with --spd one of Haines's scenes (balls:5) with its
own view, lights and fills, orbited about the middle of its spheres; Whitted's depth and shadow
samples are the viewer's defaults unless given.

One record of the results schema's "parts" suite (quantity "viewer-frame") per (device,
spheres, shading): time_ms is the time between frames shown after the warm-up; values
frames_per_s (timed frames / wall time of the loop after the warm-up), trace_ms (median of the
tracer's own time a frame: Renderer.render on cpu and cuda, the compute pass's GPU time on
wgpu), draw_ms (median of the loop's own time a draw), draws_per_frame, rays_per_frame and
rays_per_s (every ray cast, over the wall time), window_cap_fps, and update_ms with --animate.
"""

import argparse
import json
import sys
import threading
import time
from dataclasses import dataclass

import _harness
import numpy as np

import raybench
from raybench import Camera, RaybenchError, camera_path, lighting
from raybench.backends.wgpu.adapters import describe_raw
from raybench.bench.stats import summarize
from raybench.viewer.drawing import FrameDrawer, wgpu_tracer_here
from raybench.viewer.gpu import TextureQuad, choose_target_format, request_device
from raybench.viewer.shading import FirstShading
from raybench.viewer.state import ViewerState
from raybench.viewer.window import MAX_FPS

VIEWER_SIZE = "800x600"  # `raybench view`'s default window size (cli.options.size_option)
# The formats a Vulkan surface offers on X11 (NVIDIA's and Mesa's): the window draws through bgra8unorm.
SURFACE_FORMATS = ("bgra8unorm-srgb", "bgra8unorm")
WAIT_S = 600.0  # the longest a frame may take before the run is called stuck


@dataclass(frozen=True)
class Shown:
    """What the record needs of a frame shown."""

    trace_ms: float
    rays_cast: int
    update_ms: float | None


@dataclass
class Measured:
    record: dict
    last: object  # the last frame shown (a viewer.worker.TracedFrame)
    drawn: np.ndarray  # what the last draw left in the offscreen target, (H, W, 3) RGB, read after the timing


class Gpu:
    """The wgpu device the quad draws with, the window's: one for the run, as the window has one."""

    def __init__(self, adapter: str | None):
        self.named = adapter
        self.adapter, self.device = request_device(None, adapter)
        self.format = choose_target_format(SURFACE_FORMATS)

    def target(self, width: int, height: int):
        """The offscreen texture drawn instead of the surface's, made as the window configures its surface."""
        import wgpu

        usage = wgpu.TextureUsage.RENDER_ATTACHMENT | wgpu.TextureUsage.COPY_SRC
        return self.device.create_texture(
            size=(width, height, 1), format=self.format.configure, usage=usage, view_formats=self.format.view_formats
        )

    def finish(self, target) -> None:
        """Wait until the GPU has done all the work submitted: one texel of target read back.
        (wgpu 0.32's queue.on_submitted_work_done_sync fails in wgpu-native's bindings.)"""
        self.device.queue.read_texture(
            {"texture": target, "origin": (0, 0, 0), "mip_level": 0},
            {"offset": 0, "bytes_per_row": 256, "rows_per_image": 1},
            (1, 1, 1),
        )


def orbit(state: ViewerState, frames: int) -> list[Camera]:
    """A full turn in `frames` steps of the viewer's home camera about the middle of the spheres' centres."""
    centres = state.supply.scene.centers
    middle = tuple(float(v) for v in (centres.min(axis=0) + centres.max(axis=0)) / 2) if len(centres) else None
    home = state.home
    about = Camera(home.position, middle or home.look_at, home.up, home.fov_deg)
    return camera_path.orbit(about, frames)


def scene_of(what):
    """(scene, its name or None): an int is random_spheres(n, materials=True), the issue's; "NAME:SIZE"
    one of Haines's SPD scenes (raybench.formats.spd) with its own view, lights and fills."""
    if isinstance(what, int):
        return raybench.random_spheres(what, seed=0, materials=True), None
    from raybench.formats import spd

    name, _, size = what.partition(":")
    return spd.generate(name, int(size) if size else None).scene(), f"{name} {size or spd.SCENES[name][1]}"


def measure(gpu, device, what, width, height, shading, frames, warmup, turn, depth, samples, animate) -> Measured:
    scene, named = scene_of(what)
    spheres = len(scene)
    options = {"wgpu": {"adapter": gpu.named}} if gpu.named else {}
    state = ViewerState(
        scene,
        device=device,
        seed=0,
        options=options,
        shading=FirstShading(shading, depth, samples),
        animate=animate,
    )
    tracer = wgpu_tracer_here(state, gpu.device, gpu.adapter, gpu.named) if device == "wgpu" else None
    ready = threading.Event()
    drawer = FrameDrawer(state, gpu.device, TextureQuad(gpu.device, gpu.format.view), tracer, on_done=ready.set)
    target = gpu.target(width, height)
    view = target.create_view(format=gpu.format.view)
    cameras = orbit(state, turn or warmup + frames)
    total = warmup + frames
    # (when, Shown) of every frame shown; (frames shown before, ms) of every draw. Not the frames
    # themselves: a loop that kept them all would hold every frame's arrays, as the window never does,
    # and have the Renderer copy each new one out of its lent arrays (render.KEEP_LENT).
    shown, draws = [], []
    last = None
    try:
        wanted = True  # the window's first draw is asked for when it opens
        while state.frames_shown < total:
            if not wanted:
                if drawer.worker.handoff.may_trace():  # nothing in flight, nothing to show: it stopped
                    raise RaybenchError(f"{device}: the viewer stopped: {state.title()}")
                if not ready.wait(WAIT_S):
                    raise RaybenchError(f"{device}: no frame in {WAIT_S:.0f} s: {state.title()}")
            ready.clear()
            before = state.frames_shown
            # The camera of the next request, as a user's drag would have moved it by then.
            state.camera = cameras[state.requests_made % len(cameras)]
            start = time.perf_counter()
            traced = drawer.draw(view, width, height)
            if traced is not None:
                shown.append((time.perf_counter(), Shown(traced.trace_ms, traced.rays_cast, traced.update_ms)))
                last = traced
            if state.frames_shown < total:  # after the last frame, no next one is started
                state.camera = cameras[state.requests_made % len(cameras)]
                wanted = drawer.trace_next(width, height)
            draws.append((before, (time.perf_counter() - start) * 1e3))
        gpu.finish(target)  # the last quad drawn, not only submitted
        end = time.perf_counter()
        drawn = drawer.quad.read(target)
    finally:
        drawer.close(WAIT_S)
    timed = shown[warmup:]
    since = shown[warmup - 1][0]
    times = [b[0] - a[0] for a, b in zip(shown[warmup - 1 :], timed)]
    times[-1] += end - timed[-1][0]  # the wait for the last quad
    wall = end - since
    draw_ms = [ms for before, ms in draws if before >= warmup]
    rays = [t.rays_cast for _, t in timed]
    used = {"shading": shading, **({"scene": named} if named else {})}
    request = last.request
    if request.shading is not None:
        used.update(depth=request.shading.depth, shadow_samples=request.shading.shadow_samples)
    if gpu.named and device == "wgpu":
        used["adapter"] = gpu.named
    if animate:
        used["motion"] = "orbits"
    values = {
        "frames_per_s": frames / wall,
        "wall_s": wall,
        "trace_ms": summarize([t.trace_ms for _, t in timed])["median"],
        "draw_ms": summarize(draw_ms)["median"],
        "draws_per_frame": len(draw_ms) / frames,
        "rays_per_frame": float(np.median(rays)),
        "rays_per_s": sum(rays) / wall,
        "window_cap_fps": MAX_FPS * frames / len(draw_ms),
    }
    if animate:
        values["update_ms"] = summarize([t.update_ms for _, t in timed])["median"]
    record = _harness.part(
        "viewer-frame", device, [t * 1e3 for t in times], spheres=spheres, width=width, height=height,
        options=used, values=values,
    )  # fmt: skip
    return Measured(record, last, drawn)


def parse_size(parser, text: str) -> tuple[int, int]:
    try:
        width, height = (int(v) for v in text.lower().split("x"))
    except ValueError:
        parser.error(f"--size: must be WIDTHxHEIGHT, e.g. 1680x1050, got {text!r}")
    if not (1 <= width <= 16384 and 1 <= height <= 16384):
        parser.error(f"--size: each side from 1 to 16384, got {text!r}")
    return width, height


def main(argv=None, seen: list | None = None) -> int:
    """seen: where a caller (the tests) gets each point's Measured, pixels and all."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--device", action="append", choices=["cpu", "cuda", "wgpu"], help="repeat for more")
    parser.add_argument("--spheres", action="append", type=int, help="repeat for more (default 1000 and 10000)")
    parser.add_argument("--spd", action="append", default=[],
                        help="an SPD scene NAME:SIZE (e.g. balls:5), its own view and lights, instead of random "
                        "spheres; repeat for more")  # fmt: skip
    parser.add_argument("--size", default=VIEWER_SIZE, help=f"the window's size (default {VIEWER_SIZE}, the viewer's)")
    parser.add_argument("--shading", action="append", choices=["whitted", "thesis"], help="repeat for both")
    parser.add_argument("--depth", type=int, help="whitted: bounces (default: the viewer's)")
    parser.add_argument("--shadow-samples", type=int, help="whitted: shadow rays a light (default: the viewer's)")
    parser.add_argument("--warmup", type=int, default=3, help="frames shown before the timing (default 3)")
    parser.add_argument("--orbit", type=int, help="frames a full turn of the camera (default: a point's frames)")
    parser.add_argument("--animate", action="store_true", help="the spheres move too, as `raybench view --animate`")
    parser.add_argument("--adapter", help="wgpu's adapter, by a part of its name (default: the best GPU)")
    _harness.add_common(parser, frames=60)
    args = parser.parse_args(argv)
    _harness.check_common(parser, args)
    width, height = parse_size(parser, args.size)
    if args.warmup < 1:
        parser.error(f"--warmup: at least 1 (the first frame compiles and builds), got {args.warmup}")
    if args.orbit is not None and args.orbit < 2:
        parser.error(f"--orbit: at least 2 frames a turn, got {args.orbit}")
    if any(n < 1 for n in args.spheres or []):
        parser.error("--spheres: at least 1")
    try:
        if args.depth is not None:
            lighting.check_depth(args.depth)
        if args.shadow_samples is not None:
            lighting.check_shadow_samples(args.shadow_samples)
        gpu = Gpu(args.adapter)
    except RaybenchError as exc:
        parser.error(str(exc))
    settings = {
        "size": args.size, "frames": args.frames, "warmup": args.warmup, "orbit": args.orbit,
        "animate": args.animate, "target_format": gpu.format.view, "max_fps": MAX_FPS,
        "quad_adapter": describe_raw(gpu.adapter).label(),
    }  # fmt: skip
    with _harness.Records("viewer_frames", args, settings) as out:
        for _ in range(args.rounds):
            for shading in args.shading or ["whitted"]:
                for device in args.device or ["cuda", "wgpu"]:
                    for n in args.spd or args.spheres or [1000, 10_000]:
                        try:
                            got = measure(
                                gpu, device, n, width, height, shading, args.frames, args.warmup, args.orbit,
                                args.depth, args.shadow_samples, args.animate,
                            )  # fmt: skip
                        except RaybenchError as exc:  # the point is not measured: said on stderr, the run goes on
                            error = {"device": device, "spheres": n, "shading": shading, "error": str(exc)}
                            print(json.dumps(error), file=sys.stderr)
                            continue
                        out.write(got.record)
                        if seen is not None:
                            seen.append(got)
    return 0


if __name__ == "__main__":
    sys.exit(main())
