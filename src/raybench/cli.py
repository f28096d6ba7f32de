"""The command line: raybench render | view | info | bench | report.

Every mistake a user can make ends as one line on stderr and exit code 2; no
traceback reaches the terminal for input we can name.
"""

from __future__ import annotations

import json
import os
import re
import sys
import time
from pathlib import Path

import click

from . import __version__
from .backends.limits import ACCELS, BUILDS, KERNELS
from .errors import RaybenchError, device_failure, one_line
from .files import check_writable
from .lighting import SHADINGS
from .scene import LAYOUTS

SIZE_HELP = "image size as WIDTHxHEIGHT, e.g. 1680x1050"


def parse_pair(text: str, option: str, example: str) -> tuple[int, int]:
    """'AxB' -> (A, B), for --size and --block."""
    match = re.fullmatch(r"\s*(\d+)\s*[xX]\s*(\d+)\s*", text, re.ASCII)
    if not match:
        raise RaybenchError(f"{option}: must be two whole numbers joined by x, e.g. {example}, got {text!r}")
    return int(match[1]), int(match[2])


def parse_size(text: str) -> tuple[int, int]:
    from .backends.limits import check_size

    width, height = parse_pair(text, "--size", "800x600")
    check_size(width, height)
    return width, height


def parse_block(text: str) -> tuple[int, int]:
    return parse_pair(text, "--block", "16x16")


def device_options(
    *, threads=None, block=None, workgroup=None, adapter=None, kernel=None, accel=None, build=None
) -> dict:
    """The device options given on the command line (render's and view's),
    parsed: one that does not apply to the device is refused by the backend,
    in one line. Those not given are left to the backend's defaults."""
    options = {}
    if kernel is not None:
        options["kernel"] = kernel
    if accel is not None:
        options["accel"] = accel
    if build is not None:
        options["build"] = build
    if threads is not None:
        options["threads"] = threads
    if block is not None:
        options["block"] = parse_block(block)
    if workgroup is not None:
        options["workgroup"] = parse_pair(workgroup, "--workgroup", "16x16")
    if adapter is not None:
        options["adapter"] = adapter
    return options


def options_by_device(options: dict) -> dict[str, dict]:
    """Each device's share of device_options(), as backends.OPTIONS names
    them: the window switches device live, and each takes its own."""
    from .backends import DEVICES, OPTIONS

    return {device: {k: v for k, v in options.items() if k in OPTIONS[device]} for device in DEVICES}


def check_output(path: Path, option: str = "-o", suffix: str = ".png") -> None:
    """Refuse an output we could not write before spending time on a render."""
    if path.suffix.lower() != suffix:
        raise RaybenchError(f"{option} {path}: the output must be a {suffix} file")
    folder = path.parent if str(path.parent) else Path(".")
    if not folder.is_dir():
        raise RaybenchError(f"{option} {path}: folder {folder} does not exist")
    if path.is_dir():
        raise RaybenchError(f"{option} {path}: is a folder; give a file name")
    if not os.access(folder, os.W_OK) or (path.exists() and not os.access(path, os.W_OK)):
        raise RaybenchError(f"{option} {path}: not writable; choose another path")
    # os.access answers for the permissions only (and yes to root): creating a
    # file there answers for read-only file systems and the rest too.
    check_writable(path, option)


def load_scene(scene_file, spheres, seed, materials=False, layout=None):
    """The scene of --scene (a file, or an example's name: raybench.examples)
    or --spheres N (--seed, --materials, --layout)."""
    from . import examples
    from .scene import Scene, random_spheres

    if (scene_file is None) == (spheres is None):
        raise RaybenchError("give exactly one of --scene FILE or --spheres N")
    if scene_file is not None:
        given = [name for name, value in (("--seed", seed), ("--materials", materials), ("--layout", layout)) if value]
        if seed is not None or given:
            raise RaybenchError(f"{'--seed' if seed is not None else given[0]} applies to --spheres only")
        if scene_file in examples.NAMES and not Path(scene_file).exists():
            return Scene.load(examples.path(scene_file))
        return Scene.load(scene_file)
    return random_spheres(spheres, 0 if seed is None else seed, materials=materials, layout=layout or "even")


def shading_options(shading, depth, shadow_samples) -> dict:
    """render()'s shading arguments from --shading, --depth, --shadow-samples."""
    if shading != "whitted" and (depth is not None or shadow_samples is not None):
        raise RaybenchError("--depth and --shadow-samples apply to --shading whitted only")
    return {"shading": shading, "depth": depth, "shadow_samples": shadow_samples}


# --- options that render and view share, each written once ------------------------


def stacked(*decorators):
    """One decorator of several click options, shown in the order given."""

    def apply(f):
        for decorator in reversed(decorators):
            f = decorator(f)
        return f

    return apply


def scene_options(verb: str):
    """--scene, --spheres, --seed, --materials: the scene to render or show."""
    return stacked(
        click.option(
            "--scene",
            "scene_file",
            type=click.Path(dir_okay=False),
            help=f"scene JSON file to {verb}, or the name of an example: whitted",
        ),
        click.option("--spheres", type=int, help=f"{verb} N random spheres instead of a scene file"),
        click.option("--seed", type=int, help="seed of the random spheres (default 0)"),
        click.option(
            "--materials",
            is_flag=True,
            help="the random spheres with mixed materials (plastic, mirrors, glass) and an area light",
        ),
    )


def shading_option_group():
    """--shading, --depth, --shadow-samples."""
    return stacked(
        click.option(
            "--shading",
            type=click.Choice(SHADINGS),
            default="thesis",
            show_default=True,
            help="thesis: each sphere's colour darkened towards its rim; whitted: the scene's lights with "
            "shadows, mirrors and glass",
        ),
        click.option("--depth", type=int, help="whitted: bounces of reflection and refraction (default 5)"),
        click.option(
            "--shadow-samples", type=int, help="whitted: shadow rays to each area light, for soft shadows (default 4)"
        ),
    )


def size_option(help_text: str = SIZE_HELP):
    return click.option("--size", default="800x600", show_default=True, help=help_text)


def device_option(what: str = "where to trace"):
    return click.option(
        "--device",
        default="auto",
        show_default=True,
        type=click.Choice(["auto", "cpu", "cuda", "wgpu"]),
        help=f"{what}: auto picks cuda when a usable NVIDIA GPU is present, else wgpu on a GPU, else cpu",
    )


def adapter_option(whose: str = "wgpu"):
    return click.option(
        "--adapter",
        help=f"{whose}: the adapter whose name contains this (default: the best GPU; a CPU "
        "driver such as llvmpipe only when named)",
    )


def tracer_options(adapter_whose: str = "wgpu"):
    """The options device_options() takes: how to trace, on each device."""
    return stacked(
        click.option("--threads", type=int, help="cpu: number of threads (default: all cores)"),
        click.option(
            "--block",
            help=(
                "cuda: thread block shape XxY (default 8x8 for the fast kernel and the BVH walked a ray at a time, "
                "8x4 for its packets on large trees, 16x16 simple)"
            ),
        ),
        click.option("--workgroup", help="wgpu: workgroup shape XxY (default 16x16)"),
        adapter_option(adapter_whose),
        click.option(
            "--accel",
            type=click.Choice(ACCELS),
            help="bvh: walk a bounding volume hierarchy (the default); none: brute force, every sphere for "
            "every ray (the thesis's algorithm; the default where --kernel is given). Same picture",
        ),
        click.option(
            "--kernel",
            type=click.Choice(KERNELS),
            help="brute force only: simple, the thesis's loop, a pixel at a time; fast (its default on cpu and "
            "cuda), rays grouped and certain misses skipped, the same picture; wgpu has simple only",
        ),
        build_option(),
    )


def build_option(multiple: bool = False):
    return click.option(
        "--build",
        "builds" if multiple else "build",
        multiple=multiple,
        type=click.Choice(BUILDS),
        help="cuda and wgpu, with the BVH: where its tree is built: host (the CPU's binned SAH tree, uploaded; the "
        "default) or gpu (an LBVH built on the GPU, where it is walked)" + ("; repeat for both" if multiple else ""),
    )


def cluster_options():
    """--workers, --scheduler, --tile, --connect-timeout: where a Dask cluster's workers trace."""
    return stacked(
        click.option(
            "--workers",
            type=click.IntRange(min=1),
            help="trace across an embedded Dask cluster of N worker processes on this machine (one per GPU on "
            "cuda; on the cpu, sharing the cores)",
        ),
        scheduler_option("trace across the running Dask cluster whose scheduler is at this address"),
        click.option(
            "--tile",
            type=int,
            help="across a cluster: rows of one frame's tiles, a multiple of 8 (default: about 4 tiles a worker)",
        ),
        connect_timeout_option(),
    )


def scheduler_option(what: str):
    return click.option("--scheduler", help=f"{what}, e.g. tcp://10.0.0.5:8786 (default: $RAYBENCH_SCHEDULER)")


def connect_timeout_option():
    return click.option(
        "--connect-timeout",
        type=click.FloatRange(min=0.1, max=3600),
        default=10.0,
        show_default=True,
        help="seconds to try the scheduler's address before giving up",
    )


# --- the commands -------------------------------------------------------------------


@click.group(context_settings={"help_option_names": ["-h", "--help"]})
@click.version_option(version=__version__, prog_name="raybench")
def main():
    """raybench: the thesis's ray tracer on CPU and GPU, and what the GPU buys."""


@main.command()
@scene_options("render")
@click.option(
    "--layout",
    type=click.Choice(LAYOUTS),
    help="how the random spheres are spread: even (the default, the benchmark's), or a denser scene: dense "
    "(larger, overlapping spheres), clusters, deep (depths 1 to 1,000)",
)
@size_option()
@device_option()
@tracer_options()
@shading_option_group()
@click.option(
    "-o",
    "--output",
    type=click.Path(path_type=Path),
    help="PNG file to write (default render.png); with --path, the folder of the frames",
)
@click.option(
    "--path",
    "camera_path",
    help="a frame sequence: 'orbit' (a full turn about the camera's look_at) or a keyframes JSON file "
    "(docs: raybench.camera_path); one PNG a frame in the folder -o, across the cluster's workers",
)
@click.option("--frames", type=int, help="--path: frames of the sequence (default 240)")
@click.option(
    "--png-level",
    type=int,
    help="zlib's level of the PNGs, 0 (none) to 9 (smallest); default 1, which encodes several times faster "
    "than 6 in files a little larger",
)
@click.option(
    "--gif",
    type=click.Path(path_type=Path),
    help="--path: also the whole sequence as one animated GIF at this path, 25 frames a second (Pillow, a palette a "
    "frame)",
)
@cluster_options()
def render(
    scene_file,
    spheres,
    seed,
    materials,
    layout,
    size,
    device,
    threads,
    block,
    workgroup,
    adapter,
    accel,
    kernel,
    build,
    shading,
    depth,
    shadow_samples,
    output,
    camera_path,
    frames,
    png_level,
    gif,
    workers,
    scheduler,
    tile,
    connect_timeout,
):
    """Trace one frame and save it as a PNG; or, with --path, a sequence of
    frames. With --workers or --scheduler, across a Dask cluster's workers:
    one frame in tiles of rows, a sequence in runs of frames."""
    from .backends import resolve
    from .render import PNG_LEVEL, check_png_level
    from .render import render as render_frame

    scene = load_scene(scene_file, spheres, seed, materials, layout)
    width, height = parse_size(size)
    shaded = shading_options(shading, depth, shadow_samples)
    options = device_options(
        threads=threads, block=block, workgroup=workgroup, adapter=adapter, kernel=kernel, accel=accel, build=build
    )
    scheduler = scheduler or os.environ.get("RAYBENCH_SCHEDULER") or None
    if workers is not None and scheduler is not None:
        raise RaybenchError("give --workers (an embedded cluster) or --scheduler (a running one), not both")
    if camera_path is None and frames is not None:
        raise RaybenchError("--frames applies to --path only")
    if png_level is not None:
        check_png_level(png_level)
    if gif is not None:
        if camera_path is None:
            raise RaybenchError("--gif applies to --path only")
        check_output(gif, "--gif", ".gif")
    if camera_path is not None:
        if tile is not None:
            raise RaybenchError("--tile applies to one frame; a sequence's tasks are whole frames")
        level = PNG_LEVEL if png_level is None else png_level
        return _render_sequence(scene, camera_path, frames, output, width, height, device, shaded, options,
                                workers, scheduler, connect_timeout, level, gif)  # fmt: skip
    level = PNG_LEVEL if png_level is None else png_level
    output = output or Path("render.png")
    check_output(output)
    if workers is not None or scheduler is not None:
        return _render_tiles(scene, output, width, height, device, shaded, options, workers, scheduler, tile,
                             connect_timeout, level)  # fmt: skip
    if tile is not None:
        raise RaybenchError("--tile applies across a cluster: give --workers N or --scheduler ADDR")
    device = resolve(device, adapter)
    start = time.perf_counter()
    frame = render_frame(scene, width=width, height=height, device=device, **shaded, **options)
    elapsed = time.perf_counter() - start
    frame.save(output, level)
    built = f", BVH built in {frame.build_s * 1e3:.1f} ms" if frame.build_s is not None else ""
    if frame.build_s is not None:
        from . import bvh

        if bvh.compiling_elsewhere():
            built += " (by the builder's Python, as it compiles for later runs)"
        elif bvh.last_build_in_python():
            built += " (by the builder's Python: for one picture, quicker than starting Numba's CPU compiler)"
    rays = ""
    if frame.rays is not None:
        rays = ", rays: " + ", ".join(f"{n:,} {kind}" for kind, n in frame.rays.items())
    click.echo(
        f"wrote {output}: {width}x{height}, {len(scene):,} spheres, {frame.device}, "
        f"{elapsed:.2f} s including compilation{built}{rays}"
    )


def _cluster(workers, device, scheduler, connect_timeout):
    from . import cluster

    return cluster.Cluster(workers=workers, device=device, scheduler=scheduler, timeout=connect_timeout)


def _render_tiles(scene, output, width, height, device, shaded, options, workers, scheduler, tile, timeout, level):
    """render --workers/--scheduler: one frame in tiles across the cluster."""
    from . import cluster

    start = time.perf_counter()
    with _cluster(workers, device, scheduler, timeout) as running:
        frame = cluster.render(running.client, scene, None, width, height, device, rows=tile, **shaded, **options)
        count = running.workers
    frame.save(output, level)
    click.echo(
        f"wrote {output}: {width}x{height}, {len(scene):,} spheres, {frame.device}, in tiles on {count} workers, "
        f"{time.perf_counter() - start:.2f} s including the cluster's start"
    )


def _render_sequence(scene, spec, frames, output, width, height, device, shaded, options, workers, scheduler,
                     timeout, level, gif):  # fmt: skip
    """render --path: a sequence of frames across the cluster, written as they
    arrive, with a progress bar; those on disk already are kept."""
    from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeRemainingColumn

    from . import camera_path, cluster

    if output is None:
        raise RaybenchError("--path: give -o DIR, the folder to write the frames in")
    if output.suffix.lower() == ".png":
        raise RaybenchError(f"-o {output}: with --path, a folder for the frames, not a .png file")
    if output.exists() and not output.is_dir():
        raise RaybenchError(f"-o {output}: is a file; give a folder for the frames")
    cameras = camera_path.load(spec, 240 if frames is None else frames, scene.camera)
    if not output.parent.is_dir():
        raise RaybenchError(f"-o {output}: folder {output.parent} does not exist")
    output.mkdir(exist_ok=True)
    check_writable(cluster.frame_path(output, 0), "-o")
    start = time.perf_counter()
    with _cluster(workers, device, scheduler, timeout) as running:
        columns = (TextColumn("{task.description}"), BarColumn(), MofNCompleteColumn(), TimeRemainingColumn())
        with Progress(*columns, transient=True) as progress:
            bar = progress.add_task(f"frames on {running.workers} workers", total=len(cameras))
            cluster.render_sequence(running.client, scene, cameras, output, width, height, device, **shaded,
                                    on_frame=lambda n, path: progress.advance(bar), png_level=level,
                                    **options)  # fmt: skip
    click.echo(
        f"wrote {len(cameras)} frames to {output}/: {width}x{height}, {len(scene):,} spheres, "
        f"{time.perf_counter() - start:.2f} s including the cluster's start"
    )
    if gif is not None:
        from .gif import FPS, write_gif

        write_gif([cluster.frame_path(output, n) for n in range(len(cameras))], gif)
        click.echo(f"wrote {gif}: {len(cameras)} frames at {FPS} a second")


def _view_help() -> str:
    from .viewer.bindings import help_lines

    # "\b" keeps click from re-wrapping the key table.
    return (
        "Open a window that shows frames as fast as the device traces them.\n\n"
        "The title bar shows the device, the sphere count, the resolution, the frame time "
        "(averaged over the last second), frames per second, the shading and rays per second "
        "(under whitted shading every ray cast counts: primary, shadow, reflection, refraction). "
        "The picture is the one `raybench render` writes for the same view and shading, byte for byte.\n\n"
        "\b\nKeys:\n" + "\n".join("  " + line for line in help_lines())
    )


@main.command(help=_view_help())
@scene_options("show")
@size_option("window size as WIDTHxHEIGHT, e.g. 1680x1050")
@device_option("where to trace first (switch live with Tab)")
@tracer_options(adapter_whose="wgpu, and the window")
@shading_option_group()
@click.option(
    "--animate",
    is_flag=True,
    help="the spheres move every frame (orbits, raybench.animate), the tree following them; the title shows "
    "its update (refit or build) and the trace apart",
)
@click.option("--frames", type=click.IntRange(min=1), help="close after N traced frames are shown")
@click.option(
    "--screenshot",
    type=click.Path(path_type=Path),
    help="with --frames: save the last frame, as drawn in the window, to this PNG file",
)
def view(
    scene_file,
    spheres,
    seed,
    materials,
    size,
    device,
    threads,
    block,
    workgroup,
    adapter,
    accel,
    kernel,
    build,
    shading,
    depth,
    shadow_samples,
    animate,
    frames,
    screenshot,
):
    from . import backends
    from .lighting import Shading
    from .scene import Scene
    from .viewer import view as open_viewer

    scene = load_scene(scene_file, spheres, seed, materials)
    width, height = parse_size(size)
    shaded = shading_options(shading, depth, shadow_samples)
    # checked here, before the window opens: a Whitted frame of no spheres
    whitted = Shading.of(Scene([], [], []), depth, shadow_samples) if shading == "whitted" else None
    if screenshot is not None:
        if frames is None:
            raise RaybenchError(
                "--screenshot needs --frames N (the frame to save); in the window, P saves a screenshot"
            )
        check_output(screenshot, "--screenshot")
    device = backends.resolve(device, adapter)
    # render's options, through render's path, then each device's share of them
    options = options_by_device(
        device_options(
            threads=threads, block=block, workgroup=workgroup, adapter=adapter, kernel=kernel, accel=accel, build=build
        )
    )
    # Bad options are refused before the window opens, on each device they would
    # reach: the first one, the cpu, cuda where there is one (a switch to it says
    # so otherwise), and wgpu where it is the first or was given its own options
    # (an adapter is looked for only then).
    for name, given in options.items():
        if not given or (name == "wgpu" and device != "wgpu" and not {"adapter", "workgroup"} & given.keys()):
            continue
        if name == "cuda" and device != "cuda":
            try:
                backends.resolve("cuda")
            except RaybenchError:
                continue
        _check_options(name, given, whitted)
    seed = None if scene_file is not None else (0 if seed is None else seed)
    window = open_viewer(
        scene,
        device=device,
        seed=seed,
        size=(width, height),
        options=options,
        frames=frames,
        screenshot=screenshot,
        animate=animate,
        **shaded,
    )
    if frames is not None and window.state.frames_shown < frames:
        raise RaybenchError(
            f"the window was closed after {window.state.frames_shown} of {frames} frames"
            + ("; no screenshot written" if screenshot is not None else "")
        )
    if frames is not None:
        shown = window.state.shown
        lit = "" if shown.request.shading is None else ", whitted"
        last = (
            f"{shown.frame.width}x{shown.frame.height}, {shown.request.count:,} spheres, {shown.frame.device}{lit}, "
            f"frame {frames} traced in {shown.trace_ms:.1f} ms"
        )
        click.echo(
            f"wrote {screenshot}: {last}" if screenshot is not None else f"showed {frames} frames; the last: {last}"
        )


def _check_options(device: str, options: dict, whitted=None) -> None:
    """Refuse bad device options (--threads, --block, --accel, ...) before a
    window opens: the backend itself checks them, on an empty 1x1 tracer
    (with whitted, a lighting.Shading of no spheres: under Whitted shading)."""
    import numpy as np

    from . import backends

    if whitted is not None:
        options = {**options, "whitted": whitted}
    backends.tracer(device, np.zeros((7, 0), np.float32), 1, 1, **options).close()


@main.command()
@click.option("--json", "as_json", is_flag=True, help="print the machine description as JSON")
def info(as_json):
    """Describe this machine: processors, their FP32 rates, library versions."""
    from .machine import describe

    desc = describe()
    if as_json:
        click.echo(json.dumps(desc, indent=2))
        return
    c = desc["cpu"]
    click.echo(f"OS        {desc['os']}")
    click.echo(f"CPU       {c['model']} ({c['arch']})")
    click.echo(
        f"          {c['physical_cores']} cores, {c['logical_cpus']} logical CPUs, {c['clock_ghz']} GHz, "
        f"{c['memory_gib']} GiB memory"
    )
    click.echo(
        f"          SIMD {c['simd']} ({c['simd_bits']} bits = {c['fp32_lanes']} float32 lanes), "
        f"{c['fma_units_per_core']} FMA units per core (assumed)"
    )
    click.echo(
        f"          FP32 peak {c['fp32_gflops']:,} GFLOP/s = {c['physical_cores']} cores x {c['clock_ghz']} GHz "
        f"x {c['fp32_lanes']} lanes x 2 x {c['fma_units_per_core']} FMA units"
    )
    if not desc["gpus"]:
        from .backends import cuda_available

        click.echo("GPU       none usable" + ("" if cuda_available() else f": {_cuda_reason()}"))
    for g in desc["gpus"]:
        click.echo(f"GPU       {g['name']} (compute capability {g['compute_capability']}, driver {g['driver']})")
        click.echo(
            f"          {g['multiprocessors']} multiprocessors x {g['fp32_lanes_per_sm']} FP32 lanes, "
            f"{g['clock_ghz']} GHz, memory {g['memory_gib']} GiB at {g['memory_clock_ghz']} GHz"
        )
        if g["fp32_gflops"]:
            click.echo(
                f"          FP32 peak {g['fp32_gflops']:,} GFLOP/s = {g['multiprocessors']} x "
                f"{g['fp32_lanes_per_sm']} x 2 x {g['clock_ghz']} GHz"
            )
    adapters = desc["wgpu_adapters"]
    if not adapters:
        click.echo("wgpu      no adapter found (no Vulkan, Metal, D3D12 or OpenGL driver wgpu can use)")
    for i, a in enumerate(adapters):
        note = "" if a["type"] in ("DiscreteGPU", "IntegratedGPU") else "  (not a GPU: used only with --adapter)"
        click.echo(
            f"{'wgpu' if i == 0 else ''}{'':{10 - (4 if i == 0 else 0)}}{a['name']} ({a['backend']}, {a['type']}){note}"
        )
    versions = ", ".join(f"{k} {v}" for k, v in desc["versions"].items() if v)
    click.echo(f"Versions  {versions}")


@main.command()
@click.option(
    "--suite",
    "suites",
    multiple=True,
    default=("thesis",),
    show_default=True,
    help="thesis, constant-vs-runtime, tuning, scaling, secondary (Whitted frames: shadows, mirrors, "
    "glass), dynamic (spheres that move every frame: the tree's update and the frame), or all (every "
    "one; brute force past a frame-time cap is skipped in scaling and secondary); repeat for several",
)
@click.option(
    "--device", "devices", multiple=True, help="cpu, cuda or wgpu; repeat for several (default: every device present)"
)
@adapter_option()
@click.option(
    "--duration", type=float, help="seconds of timed frames per point, after warm-up (default 10; 0.5 with --quick)"
)
@click.option(
    "--kernel",
    "kernels",
    multiple=True,
    type=click.Choice(KERNELS),
    help="kernels for the thesis and tuning suites; repeat for both (default fast; "
    "constant-vs-runtime always uses simple, the only one with a compile-time count, "
    "and so does secondary's brute force, the only one Whitted shading has)",
)
@click.option(
    "--accel",
    "accels",
    multiple=True,
    type=click.Choice(ACCELS),
    help="bvh, none (brute force), or both repeated (the default): the thesis, tuning, scaling and "
    "secondary suites measure each; constant-vs-runtime and test 7 are brute force only",
)
@build_option(multiple=True)
@click.option("--quick", is_flag=True, help="a reduced set of points: about a minute on a 2-core laptop")
@click.option(
    "--out",
    "out_dir",
    type=click.Path(path_type=Path),
    help="folder for the results and the report (default: raybench-results/<machine>, or /cluster with --scheduler)",
)
@click.option(
    "--label",
    help="short machine name used in the report (default: from the GPU or CPU name; with --scheduler, each "
    "machine's host name, after this label and a dash if given)",
)
@click.option("--seed", type=int, default=0, show_default=True, help="seed of the random scenes")
@click.option("--no-report", is_flag=True, help="only write the results; skip the report")
@scheduler_option(
    "run the suites on every machine of the running Dask cluster whose scheduler is at this address, "
    "once a machine (on one of its workers), with its own devices and description; each machine's "
    "records arrive when its run ends, into one results file and one report, the machines side by side"
)
@connect_timeout_option()
def bench(
    suites,
    devices,
    adapter,
    kernels,
    accels,
    builds,
    duration,
    quick,
    out_dir,
    label,
    seed,
    no_report,
    scheduler,
    connect_timeout,
):
    """Run the thesis's experiments on this machine, then write a report;
    with --scheduler, on every machine of a Dask cluster.

    Results go to a JSON Lines file, one record per point as soon as it is
    measured (across a cluster: each machine's as its run ends): an
    interrupted run (Ctrl-C) keeps every record written.
    """
    import datetime

    from .bench import runner
    from .bench import suites as suites_mod
    from .bench.results import ResultsWriter

    chosen = suites_mod.SUITES if "all" in suites else tuple(dict.fromkeys(suites))
    for s in chosen:
        if s not in suites_mod.SUITES:
            raise RaybenchError(f"--suite: unknown suite {s!r}; choose from {', '.join(suites_mod.SUITES)} or all")
    scheduler = scheduler or os.environ.get("RAYBENCH_SCHEDULER") or None
    if scheduler is not None and "all" in suites:
        chosen = tuple(s for s in chosen if s != "multi-gpu")  # it starts workers of its own: one machine's
    if duration is None:
        duration = 0.5 if quick else 10.0
    if not 0.05 <= duration <= 3600:
        raise RaybenchError(f"--duration: must be from 0.05 to 3600 seconds, got {duration:g}")
    if seed < 0:
        raise RaybenchError(f"--seed: must be >= 0, got {seed}")
    if label is not None and not re.fullmatch(r"[A-Za-z0-9._-]+", label):
        raise RaybenchError(f"--label: use letters, digits, '.', '_' and '-' only, got {label!r}")
    if out_dir is not None and out_dir.exists() and not out_dir.is_dir():
        raise RaybenchError(f"--out {out_dir}: is a file, not a folder")
    settings = {
        "suites": list(chosen),
        "devices": list(dict.fromkeys(devices)),  # none: each machine's own, as plan() finds them
        "kernels": list(dict.fromkeys(kernels)) or ["fast"],
        "accels": list(dict.fromkeys(accels)) or list(ACCELS),
        "builds": list(dict.fromkeys(builds)),
        "duration_s": duration,
        "quick": quick,
        "seed": seed,
        "adapter": adapter,
    }
    stamp = datetime.datetime.now().strftime("%Y%m%d-%H%M%S")
    if scheduler is not None:
        from . import cluster

        out_dir = out_dir or Path("raybench-results") / (label or "cluster")
        results_path = out_dir / f"results-{stamp}.jsonl"
        with _cluster(None, "auto", scheduler, connect_timeout) as running:
            machines = cluster.bench_workers(running.client)
            click.echo(
                f"{', '.join(settings['suites'])} on {len(machines)} machine{'s' if len(machines) != 1 else ''} "
                f"of {scheduler}, {duration:g} s a point; results: {results_path}"
            )
            with ResultsWriter(results_path) as writer:
                _bench_into(
                    writer,
                    results_path,
                    lambda: cluster.bench(running.client, settings, label, lambda rs: [writer.write(r) for r in rs]),
                )
    else:
        points, info = runner.plan(settings, label)
        label = info["label"]
        out_dir = out_dir or Path("raybench-results") / label
        if out_dir.exists() and not out_dir.is_dir():
            raise RaybenchError(f"--out {out_dir}: is a file, not a folder")
        results_path = out_dir / f"results-{stamp}.jsonl"
        devices = info["settings"]["devices"]
        click.echo(f"{len(points)} points on {', '.join(devices)}, {duration:g} s each; results: {results_path}")
        with ResultsWriter(results_path) as writer:
            _bench_into(
                writer,
                results_path,
                lambda: runner.run(points, writer, info, duration, seed, progress=sys.stderr.isatty()),
            )
    click.echo(f"wrote {writer.count} results to {results_path}")
    if not no_report:
        from .bench import report

        path = report.write_report([results_path], out_dir / f"report-{stamp}")
        click.echo(f"report: {path}")


def _bench_into(writer, results_path, measure) -> None:
    """bench's measure() into writer: a failure or Ctrl-C says how many of
    its records are kept, all of them on disk already."""
    try:
        measure()
    except Exception as exc:
        failure = device_failure(exc) or (one_line(exc) if isinstance(exc, RaybenchError) else None)
        if failure is None:
            raise
        kept = (
            f"the {writer.count} finished points are in {results_path}"
            if writer.count
            else "no point had finished; no results were written"
        )
        raise RaybenchError(f"{failure}; {kept}") from None
    except KeyboardInterrupt:
        click.echo(
            f"raybench: interrupted; the {writer.count} finished points are in {results_path} "
            f"(report them with: raybench report {results_path})"
            if writer.count
            else "raybench: interrupted before the first point finished; no results were written",
            err=True,
        )
        raise SystemExit(130) from None


@main.command()
@click.option(
    "--device", "devices", multiple=True, help="cpu, cuda or wgpu; repeat for several (default: every device present)"
)
def warmup(devices):
    """Compile every kernel ahead of the first picture, into the disk cache
    (raybench.compiled): the thesis's and Whitted's shading, through the BVH
    and by brute force, and the BVH's builder. Later processes load them."""
    import numpy as np
    from rich.progress import Progress

    from . import backends, bvh, compiled, lighting
    from .camera import Camera
    from .scene import random_spheres

    devices = tuple(dict.fromkeys(devices)) or tuple(backends.present())
    for d in devices:
        if d not in backends.DEVICES:
            raise RaybenchError(f"--device: unknown device {d!r}; choose from {', '.join(backends.DEVICES)}")
        backends.resolve(d)
    scene = random_spheres(8, seed=0, materials=True)
    whitted = lighting.Shading.of(scene)
    jobs = [(d, accel, shading) for d in devices for accel in ("bvh", "none") for shading in ("thesis", "whitted")]
    with Progress(transient=True) as progress:
        task = progress.add_task("compiling", total=len(jobs) + 1)
        progress.update(task, description="the BVH's builder, for scenes of every size")
        bvh.compile_builder()
        progress.advance(task)
        for device, accel, shading in jobs:
            progress.update(task, description=f"{device}, {accel}, {shading}")
            options = {"whitted": whitted} if shading == "whitted" else {}
            with backends.tracer(device, scene.spheres, 4, 4, accel=accel, **options) as tracer:
                tracer.compile()
                tracer.trace(Camera().basis(4, 4))
            progress.advance(task)
    if "cpu" in devices:  # the thesis's brute force on the CPU: both of its kernels
        for kernel in ("fast", "simple"):
            with backends.tracer("cpu", np.zeros((7, 0), np.float32), 4, 4, kernel=kernel) as tracer:
                tracer.compile()
    if "cuda" in devices:  # the tree built on the GPU: its build, its cost and its refit
        with backends.tracer("cuda", scene.spheres, 4, 4, build="gpu") as tracer:
            tracer.update(scene.spheres)
    click.echo(f"compiled for {', '.join(devices)}; the cache: {compiled.CACHE_DIR}")


@main.command(name="report")
@click.argument("results", nargs=-1, required=True, type=click.Path(path_type=Path))
@click.option(
    "-o",
    "--out",
    "out_dir",
    type=click.Path(path_type=Path),
    default=Path("raybench-report"),
    show_default=True,
    help="folder for report.md and its plots",
)
def report_cmd(results, out_dir):
    """Turn result files (JSON Lines from `raybench bench`) into a Markdown report
    with plots and a verdict on each of the thesis's claims. Several files (two
    machines, say) go side by side in one report."""
    import warnings

    from .bench import report

    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        path = report.write_report(list(results), out_dir)
    for w in caught:
        click.echo(f"raybench: warning: {one_line(w.message)}", err=True)
    click.echo(f"report: {path}")


def _cuda_reason() -> str:
    try:
        from .backends import cuda

        return " ".join((cuda.cuda.cuda_error() or "no CUDA device was found").split())
    except ImportError as exc:
        return f"numba-cuda is not installed: {exc}"


def _interrupted() -> int:
    """Ctrl-C: one line, exit 130, and a child compiling the builder for later
    runs (bvh.one_shot) stopped rather than awaited."""
    bvh = sys.modules.get("raybench.bvh")  # not imported: no child was started
    if bvh is not None:
        bvh.stop_compiling_elsewhere()
    click.echo("raybench: interrupted", err=True)
    return 130


def run(argv=None) -> int:
    """Entry point: turn every user error into one line and exit code 2."""
    try:
        main.main(args=argv, prog_name="raybench", standalone_mode=False)
    except RaybenchError as exc:
        click.echo(f"raybench: error: {one_line(exc)}", err=True)
        return 2
    except click.exceptions.NoArgsIsHelpError as exc:
        click.echo(exc.ctx.get_help() if exc.ctx else str(exc))
        return 2
    except click.UsageError as exc:
        hint = (
            f" (see 'raybench {exc.ctx.command_path.split(' ', 1)[1]} --help')"
            if exc.ctx and " " in exc.ctx.command_path
            else " (see 'raybench --help')"
        )
        click.echo(f"raybench: error: {one_line(exc.format_message())}{hint}", err=True)
        return 2
    except click.ClickException as exc:
        click.echo(f"raybench: error: {one_line(exc.format_message())}", err=True)
        return exc.exit_code
    except (click.exceptions.Abort, KeyboardInterrupt):
        return _interrupted()
    except MemoryError:
        # Checked before the large allocations (limits.host_available_bytes);
        # this is for the rest, under a ulimit or cgroup limit we could not foresee.
        click.echo(
            "raybench: error: out of memory (a ulimit or container limit may be lower than the free memory); "
            "use a smaller --size or fewer --spheres",
            err=True,
        )
        return 2
    except Exception as exc:
        failure = device_failure(exc)
        if failure is None:
            raise
        click.echo(f"raybench: error: {one_line(failure)}; the run was stopped", err=True)
        return 2
    return 0


def entry() -> None:
    try:
        code = run()
        # A one-shot picture may have started a child that compiles the builder
        # for later runs (bvh.one_shot): it is awaited here, where Ctrl-C is caught,
        # rather than during the interpreter's shutdown, where it would print a traceback.
        bvh = sys.modules.get("raybench.bvh")  # not imported: no child was started
        if bvh is not None:
            bvh.wait_for_compiling_elsewhere()  # Ctrl-C meanwhile stops the child, quietly
    except KeyboardInterrupt:  # Ctrl-C between run's own handlers and the wait
        code = _interrupted()
    sys.exit(code)
