"""raybench render: one frame to a PNG, or a sequence of frames; across a Dask
cluster's workers with --workers or --scheduler."""

from __future__ import annotations

import os
import time
from pathlib import Path

import click

from ..errors import RaybenchError
from ..files import check_writable, make_folder
from ..scene import SPREADS
from .options import (
    check_output,
    cluster_options,
    device_option,
    device_options,
    load_scene,
    open_cluster,
    parse_size,
    scene_options,
    scheduler_security,
    shading_option_group,
    shading_options,
    size_option,
    tracer_options,
)


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
    tls_ca,
    tls_cert,
    tls_key,
    tile,
    connect_timeout,
):
    """Trace one frame and save it as a PNG; or, with --path, a sequence of
    frames. With --workers or --scheduler, across a Dask cluster's workers:
    one frame in tiles of rows, a sequence in runs of frames."""
    from ..backends import resolve
    from ..render import PNG_LEVEL, check_png_level
    from ..render import render as render_frame
    from .compiling import announced

    scene = load_scene(scene_file, spheres, seed, materials, layout)
    width, height = parse_size(size)
    shaded = shading_options(shading, depth, shadow_samples)
    options = device_options(
        threads=threads, block=block, workgroup=workgroup, adapter=adapter, kernel=kernel, accel=accel, build=build
    )
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
    if camera_path is not None:
        if tile is not None:
            raise RaybenchError("--tile applies to one frame; a sequence's tasks are whole frames")
        level = PNG_LEVEL if png_level is None else png_level
        return _render_sequence(scene, camera_path, frames, output, width, height, device, shaded, options,
                                workers, scheduler, security, connect_timeout, level, gif)  # fmt: skip
    level = PNG_LEVEL if png_level is None else png_level
    output = output or Path("render.png")
    check_output(output)
    if workers is not None or scheduler is not None:
        return _render_tiles(scene, output, width, height, device, shaded, options, workers, scheduler, security,
                             tile, connect_timeout, level)  # fmt: skip
    if tile is not None:
        raise RaybenchError("--tile applies across a cluster: give --workers N or --scheduler ADDR")
    device = resolve(device, adapter)
    start = time.perf_counter()
    with announced():
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
        f"wrote {output}: {width}x{height}, {len(scene):,} spheres, {frame.device}, "
        f"{elapsed:.2f} s including compilation{built}{rays}"
    )


def _render_tiles(scene, output, width, height, device, shaded, options, workers, scheduler, security, tile, timeout,
                  level):  # fmt: skip
    """render --workers/--scheduler: one frame in tiles across the cluster."""
    from .. import cluster

    start = time.perf_counter()
    with open_cluster(workers, device, scheduler, timeout, security) as running:
        frame = cluster.render(running.client, scene, None, width, height, device, cluster.ShadingOptions(**shaded),
                               rows=tile, **options)  # fmt: skip
        count = running.workers
    frame.save(output, level)
    click.echo(
        f"wrote {output}: {width}x{height}, {len(scene):,} spheres, {frame.device}, in tiles on {count} workers, "
        f"{time.perf_counter() - start:.2f} s including the cluster's start"
    )


def _render_sequence(scene, spec, frames, output, width, height, device, shaded, options, workers, scheduler,
                     security, timeout, level, gif):  # fmt: skip
    """render --path: a sequence of frames across the cluster, written as they
    arrive, with a progress bar; those on disk already are kept."""
    from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeRemainingColumn

    from .. import camera_path, cluster, sequence

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
    with open_cluster(workers, device, scheduler, timeout, security) as running:
        columns = (TextColumn("{task.description}"), BarColumn(), MofNCompleteColumn(), TimeRemainingColumn())
        with Progress(*columns, transient=True) as progress:
            bar = progress.add_task(f"frames on {running.workers} workers", total=len(cameras))
            delivery = cluster.SequenceOptions(on_frame=lambda n, path: progress.advance(bar), png_level=level)
            cluster.render_sequence(running.client, scene, cameras, output, width, height, device,
                                    cluster.ShadingOptions(**shaded), delivery, **options)  # fmt: skip
    click.echo(
        f"wrote {len(todo)} frames to {output}/"
        + (f" (the other {len(cameras) - len(todo)} were there already)" if len(todo) < len(cameras) else "")
        + f": {width}x{height}, {len(scene):,} spheres, "
        f"{time.perf_counter() - start:.2f} s including the cluster's start"
    )
    if gif is not None:
        from ..gif import FPS, write_gif

        write_gif([cluster.frame_path(output, n) for n in range(len(cameras))], gif, size=(width, height))
        click.echo(f"wrote {gif}: {len(cameras)} frames at {FPS} a second")
