"""raybench view: the real-time window."""

from __future__ import annotations

import click

from ..errors import RaybenchError
from .options import (
    check_output,
    device_option,
    frame_size,
    noted_scene,
    options_by_device,
    path_option,
    scene_device,
    scene_options,
    shading_option_group,
    size_option,
    tracer_options,
)


def _view_help() -> str:
    from ..viewer.bindings import help_lines

    # "\b" keeps click from re-wrapping the key table.
    return (
        "Open a window that shows frames as fast as the device traces them.\n\n"
        "The title bar shows the device, the sphere count, the resolution, the frame time "
        "(averaged over the last second), frames per second, the shading and rays per second "
        "(under whitted shading every ray cast counts: primary, shadow, reflection, refraction). "
        "The picture is the one `raybench render` writes for the same view and shading, byte for byte.\n\n"
        "\b\nKeys:\n" + "\n".join("  " + line for line in help_lines())
    )


@click.command(help=_view_help())
@scene_options("show")
@size_option("window size as WIDTHxHEIGHT, e.g. 1680x1050; an NFF scene's own resolution where not given")
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
@path_option("--screenshot", help_text="with --frames: save the last frame, as drawn in the window, to this PNG file")
def view(
    scene_args,
    size,
    device,
    tracer,
    shading,
    animate,
    frames,
    screenshot,
):
    from .. import backends
    from ..lighting import Shading
    from ..scene import Scene
    from ..viewer import view as open_viewer
    from ..viewer.shading import FirstShading
    from ..viewer.state import ViewerState

    scene = scene_args.load(meshes=True)
    width, height = frame_size(scene_args, size)
    shaded = shading.checked()
    scene = noted_scene(scene_args, scene, shaded)
    if animate and scene.meshes:
        raise RaybenchError("--animate moves spheres; a mesh is drawn where it is")
    # checked here, before the window opens: a Whitted frame of no spheres
    lit = None
    if shaded["shading"] == "whitted":
        lit = Shading.of(Scene([], [], []), shaded["depth"], shaded["shadow_samples"])
    if screenshot is not None:
        if frames is None:
            raise RaybenchError(
                "--screenshot needs --frames N (the frame to save); in the window, P saves a screenshot"
            )
        check_output(screenshot, "--screenshot")
    device = scene_device(scene, device, tracer.adapter)
    # render's options, through render's path, then each device's share of them
    options = options_by_device(tracer.options())
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
        _check_options(name, given, lit)
    seed = None if scene_args.scene_file is not None else (0 if scene_args.seed is None else scene_args.seed)
    state = ViewerState(
        scene, device=device, seed=seed, options=options, animate=animate, shading=FirstShading(**shaded)
    )
    window = open_viewer(state, (width, height), frames=frames, screenshot=screenshot)
    if frames is not None and window.state.frames_shown < frames:
        raise RaybenchError(
            f"the window was closed after {window.state.frames_shown} of {frames} frames"
            + ("; no screenshot written" if screenshot is not None else "")
        )
    if frames is not None:
        shown = window.state.shown
        lit = "" if shown.request.shading is None else ", whitted"
        last = (
            f"{shown.frame.width}x{shown.frame.height}, {shown.request.count:,} {scene.traced().noun}, "
            f"{shown.frame.device}{lit}, "
            f"frame {frames} traced in {shown.trace_ms:.1f} ms"
        )
        click.echo(
            f"wrote {screenshot}: {last}" if screenshot is not None else f"showed {frames} frames; the last: {last}"
        )


def _check_options(device: str, options: dict, shading=None) -> None:
    """Refuse bad device options (--threads, --block, --accel, ...) before a
    window opens: the backend itself checks them, on an empty 1x1 tracer
    (with shading, a lighting.Shading of no spheres: under Whitted shading)."""
    import numpy as np

    from .. import backends

    if shading is not None:
        options = {**options, "shading": shading}
    backends.tracer(device, np.zeros((7, 0), np.float32), 1, 1, **options).close()
