"""raybench scene: scenes written as files, for raybench and for other tracers.

- `scene spd NAME --size N -o FILE.nff`: one of Haines's Standard
  Procedural Databases (raybench.formats.spd) as NFF;
- `scene nff --scene FILE -o FILE.nff`: a scene raybench reads (JSON, NFF,
  PDB, mmCIF) as NFF, its spheres, materials, lights and camera;
- `scene pov --scene FILE -o FILE.pov`: the same as a POV-Ray 3.7 scene
  (raybench.formats.pov), an NFF's polygons too, for the size and depth
  raybench would render it at.
"""

from __future__ import annotations

from pathlib import Path

import click

from .options import SIZE_HELP, check_output, path_option

# formats.spd.SCENES's names, here so that the command line starts without NumPy
SPD_NAMES = ("balls", "tetra", "rings", "tree", "gears", "mount", "teapot")
SPD_SIZE_HELP = (
    "the SPD's size factor (default: the generator's own: 4 for balls and gears, 6 for tetra, mount and teapot, "
    "7 for rings, 11 for tree); "
    "balls has 10, 91, 820, 7,381, 66,430 and 597,871 spheres at 1 to 6"
)


@click.group(name="scene")
def scene_cmd():
    """Write scenes as files: the SPD's generators, and NFF exports."""


def _written(nff, output: Path, what: str) -> None:
    from ..formats.nff import counted
    from .out import echo

    nff.save(output)
    listed = ", ".join(counted(n, kind) for kind, n in nff.counts().items() if n) or "no primitives"
    echo(f"wrote {output}: {what}: {listed}")


@scene_cmd.command(name="spd")
@click.argument("name", type=click.Choice(SPD_NAMES))
@click.option("--size", "size", type=int, help=SPD_SIZE_HELP)
@path_option("-o", "--output", help_text="the NFF file to write (default NAME.nff)")
def spd_cmd(name, size, output):
    """One of Eric Haines's Standard Procedural Databases, generated as his
    programs generate it (view, lights, fills, primitives), written as NFF."""
    from ..formats import spd

    output = output or Path(f"{name}.nff")
    check_output(output, "-o", ".nff")
    nff = spd.generate(name, size)
    _written(nff, output, f"SPD {name} at size factor {spd.SCENES[name][1] if size is None else size}")


@scene_cmd.command(name="nff")
@click.option("--scene", "scene_file", required=True, type=click.Path(dir_okay=False),
              help="the scene to export: JSON, NFF, PDB or mmCIF, or an example's name")  # fmt: skip
@click.option("--resolution", default="512x512", show_default=True,
              help="the view's resolution written in the NFF (the SPD's is 512x512)")  # fmt: skip
@path_option("-o", "--output", help_text="the NFF file to write")
def nff_cmd(scene_file, resolution, output):
    """A raybench scene as NFF: spheres, fills (docs: the NFF page's
    mapping), lights and view. What NFF cannot say (an area light's radius,
    the ambient light, the thesis's gradient background) is left out."""
    from ..errors import RaybenchError
    from ..formats import nff
    from .options import load_scene, parse_pair

    if output is None:
        raise RaybenchError("-o: give the NFF file to write")
    check_output(output, "-o", ".nff")
    width, height = parse_pair(resolution, "--resolution", "512x512")
    if width < 1 or height < 1:
        raise RaybenchError(f"--resolution: both numbers must be at least 1, got {resolution}")
    scene = load_scene(scene_file, None, None)
    _written(nff.from_scene(scene, (width, height)), output, f"{len(scene):,} spheres from {scene_file}")


@scene_cmd.command(name="pov")
@click.option("--scene", "scene_file", required=True, type=click.Path(dir_okay=False),
              help="the scene to export: JSON, NFF, PDB or mmCIF, or an example's name")  # fmt: skip
@click.option("--size", default="800x600", show_default=True, help=SIZE_HELP)
@click.option("--depth", type=int, default=5, show_default=True,
              help="Whitted's bounces (POV-Ray's max_trace_level - 1)")  # fmt: skip
@path_option("-o", "--output", help_text="the .pov file to write")
def pov_cmd(scene_file, size, depth, output):
    """A raybench scene as a POV-Ray 3.7 scene: the picture raybench's
    Whitted shading renders at --size, for `povray +W.. +H.. -A
    File_Gamma=1.0` (the file's first lines give the command). Meshes are
    written as mesh2 triangles, an NFF's cones as POV-Ray's own cones."""
    from .. import formats
    from ..errors import RaybenchError
    from ..formats import pov
    from ..lighting import check_depth
    from .options import SceneArgs, frame_size, load_scene
    from .out import echo

    if output is None:
        raise RaybenchError("-o: give the .pov file to write")
    check_output(output, "-o", ".pov")
    check_depth(depth)
    width, height = frame_size(SceneArgs(scene_file, None, None, False), size)
    if formats.kind(scene_file) == "nff" and Path(scene_file).exists():
        from ..formats import nff

        read = nff.load(scene_file)
        pov.save(output, pov.from_nff(read, width, height, depth, name=output.name))
        held = ", ".join(nff.counted(n, kind) for kind, n in read.counts().items() if n)
    else:
        scene = load_scene(scene_file, None, None)
        pov.save(output, pov.text(scene, width, height, depth, name=output.name))
        held = scene.summary
    echo(f"wrote {output}: {held} from {scene_file}, for {width}x{height}, depth {depth}")
