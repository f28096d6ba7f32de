"""raybench render: one frame to a PNG, or a sequence of frames; across a Dask
cluster's workers with --workers or --scheduler."""

from __future__ import annotations

import os
import time
from dataclasses import dataclass
from pathlib import Path

import click

from ..errors import RaybenchError
from ..files import check_writable, make_folder
from ..scene import SPREADS, Scene
from .options import (
    check_output,
    cluster_options,
    device_option,
    frame_size,
    noted_scene,
    open_cluster,
    path_option,
    scene_device,
    scene_options,
    scheduler_security,
    shading_option_group,
    size_option,
    tracer_options,
)


@dataclass(frozen=True)
class RenderJob:
    """What `raybench render` traces and where it writes it, checked: the
    scene at width x height on device, with render()'s shading arguments
    (shaded) and device options, written as PNGs at zlib's level."""

    scene: Scene
    width: int
    height: int
    device: str
    shaded: dict
    options: dict
    output: Path | None
    level: int


@dataclass(frozen=True)
class ClusterSpec:
    """The cluster `raybench render` traces across: an embedded one of
    `workers`, or the running one at `scheduler` (with its TLS security),
    connected to within timeout seconds."""

    workers: int | None
    scheduler: str | None
    security: object
    timeout: float | None

    def open(self, device: str):
        return open_cluster(self.workers, device, self.scheduler, self.timeout, self.security)


@click.command()
@scene_options("render")
@click.option(
    "--layout",
    type=click.Choice(SPREADS),
    help="how the random spheres are spread: even (the default, the benchmark's), or a denser scene: dense "
    "(larger, overlapping spheres), clusters, deep (depths 1 to 1,000)",
)
@size_option()
@device_option()
@tracer_options()
@shading_option_group()
@path_option(
    "-o", "--output", help_text="PNG file to write (default render.png); with --path, the folder of the frames"
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
    help="zlib's level of the PNGs, 0 (none) to 9 (smallest); default 1, which encodes faster than 6 in files "
    "a little larger",
)
@path_option(
    "--gif",
    help_text="--path: also the whole sequence as one animated GIF at this path, 25 frames a second (Pillow, a "
    "palette a frame)",
)
@click.option(
    "--color",
    "colour",
    help="a mesh file (--scene FILE.obj, .ply, .stl, .gltf, .glb): the colour of every triangle, R,G,B from 0 "
    "to 1 (default 0.8,0.8,0.8)",
)
@cluster_options()
def render(
    scene_args,
    colour,
    layout,
    size,
    device,
    tracer,
    shading,
    output,
    camera_path,
    frames,
    png_level,
    gif,
    workers,
    scheduler,
    tls_ca,
    tls_cert,
    tls_key,
    tile,
    connect_timeout,
):
    """Trace one frame and save it as a PNG; or, with --path, a sequence of
    frames. With --workers or --scheduler, across a Dask cluster's workers:
    one frame in tiles of rows, a sequence in runs of frames."""
    from ..render import PNG_LEVEL, check_png_level
    from ..render import render as render_frame
    from .compiling import KIND_MESSAGE, MESSAGE, announced

    scene = scene_args.load(layout, meshes=True)
    width, height = frame_size(scene_args, size)
    shaded = shading.checked()
    scene = noted_scene(scene_args, scene, shaded, colour)
    options = tracer.options()
    scheduler = scheduler or os.environ.get("RAYBENCH_SCHEDULER") or None
    if workers is not None and scheduler is not None:
        raise RaybenchError("give --workers (an embedded cluster) or --scheduler (a running one), not both")
    security = scheduler_security(scheduler, tls_ca, tls_cert, tls_key)
    if camera_path is None and frames is not None:
        raise RaybenchError("--frames applies to --path only")
    if png_level is not None:
        check_png_level(png_level)
    if gif is not None:
        if camera_path is None:
            raise RaybenchError("--gif applies to --path only")
        check_output(gif, "--gif", ".gif")
    level = PNG_LEVEL if png_level is None else png_level
    on = ClusterSpec(workers, scheduler, security, connect_timeout)
    if camera_path is not None:
        if tile is not None:
            raise RaybenchError("--tile applies to one frame; a sequence's tasks are whole frames")
        job = RenderJob(scene, width, height, device, shaded, options, output, level)
        return _render_sequence(job, on, camera_path, frames, gif)
    output = output or Path("render.png")
    check_output(output)
    if workers is not None or scheduler is not None:
        return _render_tiles(RenderJob(scene, width, height, device, shaded, options, output, level), on, tile)
    if tile is not None:
        raise RaybenchError("--tile applies across a cluster: give --workers N or --scheduler ADDR")
    device = scene_device(scene, device, tracer.adapter)
    start = time.perf_counter()
    with announced(message=MESSAGE if not scene.meshes else KIND_MESSAGE):
        frame = render_frame(scene, width=width, height=height, device=device, **shaded, **options)
    elapsed = time.perf_counter() - start
    frame.save(output, level)
    built = f", BVH built in {frame.build_s * 1e3:.1f} ms" if frame.build_s is not None else ""
    if frame.build_s is not None:
        from ..bvh import oneshot

        if oneshot.compiling_elsewhere():
            built += " (by the builder's Python, as it compiles for later runs)"
        elif oneshot.last_build_in_python():
            built += " (by the builder's Python: for one picture, quicker than starting Numba's CPU compiler)"
    rays = ""
    if frame.rays is not None:
        rays = ", rays: " + ", ".join(f"{n:,} {kind}" for kind, n in frame.rays.items())
    click.echo(
        f"wrote {output}: {width}x{height}, {scene.summary}, {frame.device}, "
        f"{elapsed:.2f} s including compilation{built}{rays}"
    )


def _render_tiles(job: RenderJob, on: ClusterSpec, tile: int | None) -> None:
    """render --workers/--scheduler: one frame in tiles (of `tile` rows)
    across the cluster."""
    from .. import cluster

    scene, width, height, output = job.scene, job.width, job.height, job.output
    start = time.perf_counter()
    with on.open(job.device) as running:
        frame = cluster.render(running.client, scene, None, width, height, job.device,
                               cluster.ShadingOptions(**job.shaded), rows=tile, **job.options)  # fmt: skip
        count = running.workers
    frame.save(output, job.level)
    click.echo(
        f"wrote {output}: {width}x{height}, {scene.summary}, {frame.device}, in tiles on {count} workers, "
        f"{time.perf_counter() - start:.2f} s including the cluster's start"
    )


def _render_sequence(job: RenderJob, on: ClusterSpec, spec, frames: int | None, gif: Path | None) -> None:
    """render --path: the sequence `spec` (of `frames` frames) across the
    cluster, written as they arrive, with a progress bar; those on disk
    already are kept; with gif, also one animated GIF of them all."""
    from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeRemainingColumn

    from .. import camera_path, cluster, sequence

    scene, width, height, output, shaded = job.scene, job.width, job.height, job.output, job.shaded
    if output is None:
        raise RaybenchError("--path: give -o DIR, the folder to write the frames in")
    if output.suffix.lower() == ".png":
        raise RaybenchError(f"-o {output}: with --path, a folder for the frames, not a .png file")
    cameras = camera_path.load(spec, 240 if frames is None else frames, scene.camera)
    if gif is not None:
        from ..gif import check_fits

        check_fits(len(cameras), width, height)
    make_folder(output, "-o")
    # the frames there already checked before a worker starts: this sequence's, or one line
    marker = sequence.identity(scene, cameras, width, height, **shaded)
    todo = sequence.prepare(output, marker, "-o")
    check_writable(cluster.frame_path(output, todo[0] if todo else 0), "-o")
    start = time.perf_counter()
    with on.open(job.device) as running:
        columns = (TextColumn("{task.description}"), BarColumn(), MofNCompleteColumn(), TimeRemainingColumn())
        with Progress(*columns, transient=True) as progress:
            bar = progress.add_task(f"frames on {running.workers} workers", total=len(cameras))
            delivery = cluster.SequenceOptions(on_frame=lambda n, path: progress.advance(bar), png_level=job.level)
            cluster.render_sequence(running.client, scene, cameras, output, width, height, job.device,
                                    cluster.ShadingOptions(**shaded), delivery, **job.options)  # fmt: skip
    click.echo(
        f"wrote {len(todo)} frames to {output}/"
        + (f" (the other {len(cameras) - len(todo)} were there already)" if len(todo) < len(cameras) else "")
        + f": {width}x{height}, {scene.summary}, "
        f"{time.perf_counter() - start:.2f} s including the cluster's start"
    )
    if gif is not None:
        from ..gif import FPS, write_gif

        write_gif([cluster.frame_path(output, n) for n in range(len(cameras))], gif, size=(width, height))
        click.echo(f"wrote {gif}: {len(cameras)} frames at {FPS} a second")
