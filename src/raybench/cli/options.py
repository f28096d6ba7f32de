"""What the commands share: the options written once, and their parsing into
what render(), the viewer and the backends take."""

from __future__ import annotations

import functools
import os
import re
from dataclasses import asdict, dataclass
from pathlib import Path

import click

from ..backends.limits import WORKERS_PER_CORE, check_connect_timeout, check_worker_count
from ..backends.options import ACCELS, BUILDS, KERNELS
from ..errors import RaybenchError
from ..files import check_writable
from ..lighting import SHADINGS
from .molecule_options import MoleculeArgs, molecule_options, refuse_unless_molecule

SIZE_HELP = "image size as WIDTHxHEIGHT, e.g. 1680x1050; an NFF scene's own resolution where not given"


def parse_pair(text: str, option: str, example: str) -> tuple[int, int]:
    """'AxB' -> (A, B), for --size and --block."""
    match = re.fullmatch(r"\s*(\d+)\s*[xX]\s*(\d+)\s*", text, re.ASCII)
    if not match:
        raise RaybenchError(f"{option}: must be two whole numbers joined by x, e.g. {example}, got {text!r}")
    return int(match[1]), int(match[2])


def parse_size(text: str) -> tuple[int, int]:
    from ..backends.limits import check_size

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
    parsed = {
        "kernel": kernel,
        "accel": accel,
        "build": build,
        "threads": threads,
        "block": None if block is None else parse_block(block),
        "workgroup": None if workgroup is None else parse_pair(workgroup, "--workgroup", "16x16"),
        "adapter": adapter,
    }
    return {name: value for name, value in parsed.items() if value is not None}


def options_by_device(options: dict) -> dict[str, dict]:
    """Each device's share of device_options(), as backends.OPTIONS names
    them: the window switches device live, and each takes its own."""
    from ..backends import DEVICES, OPTIONS

    return {device: {k: v for k, v in options.items() if k in OPTIONS[device]} for device in DEVICES}


def check_output(path: Path, option: str = "-o", suffix: str = ".png") -> None:
    """Refuse an output we could not write before spending time on a render."""
    if path.suffix.lower() != suffix:
        raise RaybenchError(f"{option} {path}: the output must be a {suffix} file")
    folder = path.parent if str(path.parent) else Path(".")
    if not os.path.isdir(folder):
        raise RaybenchError(f"{option} {path}: folder {folder} does not exist")
    if os.path.isdir(path):
        raise RaybenchError(f"{option} {path}: is a folder; give a file name")
    if not os.access(folder, os.W_OK) or (os.path.exists(path) and not os.access(path, os.W_OK)):
        raise RaybenchError(f"{option} {path}: not writable; choose another path")
    # os.access answers for the permissions only (and yes to root): creating a
    # file there answers for read-only file systems and the rest too; and what
    # is at the path (files.output_mode: a FIFO or a device is refused, never
    # replaced; a name too long for the file system too).
    check_writable(path, option)


def load_scene(scene_file, spheres, seed, materials=False, layout=None, molecule=None, meshes=False):
    """The scene of --scene (a file, or an example's name: raybench.examples)
    or --spheres N (--seed, --materials, --layout). A file is read by its
    suffix: NFF (.nff), a molecule (.pdb, .ent, .cif, .mmcif, gzipped or
    not; molecule: its MoleculeArgs), a triangle mesh (.obj, .ply, .stl,
    .gltf, .glb: mesh_render.mesh_scene's Scene), else a JSON scene file.
    A mesh, or a scene file with meshes, only where the command draws them
    (meshes); elsewhere one line, so that no command drops them silently."""
    from .. import examples
    from ..scene import random_spheres

    if (scene_file is None) == (spheres is None):
        raise RaybenchError("give exactly one of --scene FILE or --spheres N")
    if scene_file is not None:
        given = [name for name, value in (("--seed", seed), ("--materials", materials), ("--layout", layout)) if value]
        if seed is not None or given:
            raise RaybenchError(f"{'--seed' if seed is not None else given[0]} applies to --spheres only")
        if scene_file in examples.NAMES and not Path(scene_file).exists():
            from importlib import resources

            # an example's file read where it lies, as a file of its kind (the molecule's, PDB)
            with resources.as_file(examples.path(scene_file)) as found:
                scene = _scene_file(str(found), molecule or MoleculeArgs())
        else:
            scene = _scene_file(scene_file, molecule or MoleculeArgs())
        if scene.meshes and not meshes:
            raise RaybenchError(f"--scene {scene_file}: meshes are drawn by raybench render and view only so far")
        return scene
    refuse_unless_molecule(molecule)
    return random_spheres(spheres, 0 if seed is None else seed, materials=materials, layout=layout or "even")


def _scene_file(scene_file, molecule: MoleculeArgs):
    """The Scene of a file by its suffix; what an NFF draws other than it
    says (a sphere of negative radius) is told in a note line."""
    from .. import formats
    from ..scene import Scene

    kind = formats.kind(scene_file)
    if kind != "molecule":
        refuse_unless_molecule(molecule)
    if kind == "mesh":
        from ..mesh_render import mesh_scene
        from ..meshes import load_mesh

        return mesh_scene(load_mesh(scene_file))
    if kind == "nff":
        from ..formats import nff

        loaded = nff.load(scene_file)
        for note in loaded.notes():
            click.echo(note)
        return loaded.scene()
    if kind == "molecule":
        return molecule.load(scene_file)
    return Scene.load(scene_file)


def shading_options(shading, depth, shadow_samples) -> dict:
    """render()'s shading arguments from --shading, --depth, --shadow-samples."""
    if shading != "whitted" and (depth is not None or shadow_samples is not None):
        raise RaybenchError("--depth and --shadow-samples apply to --shading whitted only")
    return {"shading": shading, "depth": depth, "shadow_samples": shadow_samples}


def shading_notes(scene, shaded: dict) -> list[str]:
    """What Whitted shading will not do for this scene, and the options it makes idle, each one
    line (stdout: a note, not an error): a scene without lights is shaded by the thesis's rule,
    which without mirrors or glass is the thesis's picture, and a user who asked for Whitted
    should not have to compare pixels to find out."""
    if shaded["shading"] != "whitted":
        return []
    traced = scene.traced()
    materials = traced.materials or ()
    bounces = any(m.reflect > 0 or m.transmit > 0 for m in materials)
    notes = []
    if not scene.lights:
        did = (
            f"the thesis's picture, each {traced.kind} darkened towards its rim"
            if not bounces
            else "the thesis's shading at each surface, its mirrors and glass still reflecting and refracting it"
        )
        notes.append(
            f"note: --shading whitted: the scene has no lights, so it is drawn by the thesis's rule: {did} "
            '(add "lights" to the scene file, or use --spheres N --materials)'
        )
    elif not bounces:
        kind = "sphere or triangle" if traced.kind == "mixed" else traced.kind
        notes.append(
            f"note: --shading whitted: no {kind} has a mirror or glass material, so there are no bounces: "
            "each light's diffuse light, highlights and shadows only"
        )
    if shaded.get("depth") is not None and not bounces:
        notes.append("note: --depth has no effect: the scene has no mirrors or glass to bounce from")
    if shaded.get("shadow_samples") is not None and not any(light.radius > 0 for light in scene.lights):
        notes.append("note: --shadow-samples has no effect: the scene has no area light (a light with a radius)")
    return notes


def noted_scene(scene_args, scene, shaded: dict, colour: str | None = None):
    """The scene, in --color where it is a mesh file's (and only there);
    the shading's notes said, a mesh file's default light among them. A
    scene no tracer takes (spheres and meshes) is refused here, before any
    output folder or cluster is made."""
    from .. import formats
    from ..mesh_render import DEFAULT_LIGHT_NOTE, recoloured

    scene.traced()
    from_mesh = scene_args.scene_file is not None and formats.kind(scene_args.scene_file) == "mesh"
    if colour is not None:
        if not from_mesh:
            raise RaybenchError("--color applies to a mesh file (--scene FILE.obj, .ply, .stl, .gltf or .glb) only")
        scene = recoloured(scene, _colour(colour))
    notes = shading_notes(scene, shaded)
    if from_mesh and notes:
        # mesh_scene gave it one default light and no mirrors: the first of
        # shading_notes' lines is a scene file's "no bounces", said here for a mesh
        notes = [DEFAULT_LIGHT_NOTE, *notes[1:]]
    for note in notes:
        click.echo(note)
    return scene


def scene_device(scene, device: str, adapter: str | None) -> str:
    """The concrete device for this scene (backends.resolve): "auto" for a
    mesh scene is the cpu, as backends.tracer picks it, the one device that
    traces triangles so far."""
    from ..backends import resolve

    if device == "auto" and scene.meshes:
        device = "cpu"
    return resolve(device, adapter)


def _colour(text: str) -> tuple:
    """--color R,G,B as three floats (their range is the mesh's check)."""
    parts = text.split(",")
    try:
        if len(parts) != 3:
            raise ValueError
        return tuple(float(p) for p in parts)
    except ValueError:
        raise RaybenchError(f"--color: three numbers from 0 to 1 as R,G,B (0.8,0.5,0.2), got {text!r}") from None


# --- options that render and view share, each written once ------------------------


def stacked(*decorators):
    """One decorator of several click options, shown in the order given."""

    def apply(f):
        for decorator in reversed(decorators):
            f = decorator(f)
        return f

    return apply


def handed_on(name: str, record, *decorators):
    """stacked(*decorators), whose values the command's function takes as one
    argument, name=record(**their values): a group of options travels as a
    record, not as one parameter each in every command that shows it."""
    probe = stacked(*decorators)(lambda: None)
    names = [param.name for param in probe.__click_params__]

    def apply(f):
        @functools.wraps(f)  # click's options already on f (its __dict__) stay the command's
        def command(*args, **kwargs):
            kwargs[name] = record(**{n: kwargs.pop(n) for n in names})
            return f(*args, **kwargs)

        return stacked(*decorators)(command)

    return apply


@dataclass(frozen=True)
class SceneArgs:
    """--scene, --spheres, --seed, --materials as given; load() checks them."""

    scene_file: str | None
    spheres: int | None
    seed: int | None
    materials: bool
    no_hydrogens: bool = False
    waters: bool = False
    style: str | None = None
    assembly: str | None = None
    copies: int | None = None

    @classmethod
    def given(cls, scene_path=None, scene_file=None, **options) -> SceneArgs:
        """The record of the options as typed: SCENE (the positional argument,
        `raybench render model.ply`) and --scene are one option given two
        ways, so giving both is refused."""
        if scene_path is not None and scene_file is not None:
            raise RaybenchError(f"give the scene once: {scene_path} or --scene {scene_file}, not both")
        return cls(scene_file=scene_path if scene_path is not None else scene_file, **options)

    def load(self, layout=None, meshes=False):
        molecule = MoleculeArgs(not self.no_hydrogens, self.waters, self.style, self.assembly, self.copies)
        return load_scene(self.scene_file, self.spheres, self.seed, self.materials, layout, molecule, meshes)


def frame_size(scene_args: SceneArgs, size: str) -> tuple[int, int]:
    """--size, parsed; where it was left at its default and the scene is an
    NFF file with a view, the view's resolution (NFF's own size of the picture)."""
    from click.core import ParameterSource

    context = click.get_current_context(silent=True)
    default = context is not None and context.get_parameter_source("size") is ParameterSource.DEFAULT
    if default and scene_args.scene_file is not None:
        from .. import formats

        if formats.kind(scene_args.scene_file) == "nff" and Path(scene_args.scene_file).exists():
            from ..formats import nff

            view = nff.load_view(scene_args.scene_file)
            if view is not None:
                return parse_size("{}x{}".format(*view.resolution))
    return parse_size(size)


@dataclass(frozen=True)
class ShadingArgs:
    """--shading, --depth, --shadow-samples as given; checked() is render()'s shading arguments."""

    shading: str
    depth: int | None
    shadow_samples: int | None

    def checked(self) -> dict:
        return shading_options(self.shading, self.depth, self.shadow_samples)


@dataclass(frozen=True)
class TracerArgs:
    """The device options as given (tracer_options); options() parses them, as device_options()."""

    threads: int | None
    block: str | None
    workgroup: str | None
    adapter: str | None
    accel: str | None
    kernel: str | None
    build: str | None

    def options(self) -> dict:
        return device_options(**asdict(self))


def scene_options(verb: str):
    """[SCENE], --scene, --spheres, --seed, --materials, and a molecule file's (molecule_options): the scene to
    render or show, handed on as scene_args, a SceneArgs (SCENE is --scene without its name:
    `raybench view model.obj`)."""
    return handed_on(
        "scene_args",
        SceneArgs.given,
        click.argument("scene_path", metavar="[SCENE]", required=False, type=click.Path(dir_okay=False)),
        click.option(
            "--scene",
            "scene_file",
            type=click.Path(dir_okay=False),
            help=f"scene file to {verb}: JSON, NFF (.nff), a molecule (.pdb, .cif, gzipped or not), a triangle "
            "mesh (.obj, .ply, .stl, .gltf, .glb: render and view); or the name of an example: whitted, meshes, mixed, "
            "1tii (a molecule)",
        ),
        click.option("--spheres", type=int, help=f"{verb} N random spheres instead of a scene file"),
        click.option("--seed", type=int, help="seed of the random spheres (default 0)"),
        click.option(
            "--materials",
            is_flag=True,
            help="the random spheres with mixed materials (plastic, mirrors, glass) and an area light",
        ),
        *molecule_options(),
    )


def shading_option_group():
    """--shading, --depth, --shadow-samples, handed on as shading, a ShadingArgs."""
    return handed_on(
        "shading",
        ShadingArgs,
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
    """The options device_options() takes: how to trace, on each device; handed on as tracer, a TracerArgs."""
    return handed_on(
        "tracer",
        TracerArgs,
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
        choice_option(
            "accel",
            ACCELS,
            "bvh: walk a bounding volume hierarchy (the default); none: brute force, every sphere for "
            "every ray (the thesis's algorithm; the default where --kernel is given). Same picture",
        ),
        choice_option(
            "kernel",
            KERNELS,
            "brute force only: simple, the thesis's loop, a pixel at a time; fast (its default on cpu and "
            "cuda), rays grouped and certain misses skipped, the same picture; wgpu has simple only",
        ),
        build_option(),
    )


def choice_option(name: str, choices, help_text: str, multiple: bool = False):
    """--name, one of choices: given once (render and view trace one way), or
    with multiple, repeated for each value wanted, handed on in the plural
    (bench measures each)."""
    dest = f"{name}s" if multiple else name
    return click.option(f"--{name}", dest, multiple=multiple, type=click.Choice(choices), help=help_text)


def path_option(*decls: str, help_text: str, **attrs):
    """An option that names a file or folder to write, handed on as a Path."""
    return click.option(*decls, type=click.Path(path_type=Path), help=help_text, **attrs)


def build_option(multiple: bool = False):
    return choice_option(
        "build",
        BUILDS,
        "cuda and wgpu, with the BVH: where its tree is built: host (the CPU's binned SAH tree, uploaded; the "
        "default) or gpu (an LBVH built on the GPU, where it is walked)" + ("; repeat for both" if multiple else ""),
        multiple,
    )


def cluster_options():
    """--workers, --scheduler (and its --tls-*), --tile, --connect-timeout: where a Dask cluster's workers trace."""
    return stacked(
        click.option(
            "--workers",
            type=int,
            callback=_checked(check_worker_count),
            help="trace across an embedded Dask cluster of N worker processes on this machine (one per GPU on "
            f"cuda; on the cpu, sharing the cores; at most {WORKERS_PER_CORE} a core, and as many as the memory "
            "holds)",
        ),
        scheduler_option("trace across the running Dask cluster whose scheduler is at this address"),
        tls_options(),
        click.option(
            "--tile",
            type=int,
            help="across a cluster: rows of one frame's tiles, a multiple of 8 (default: about 4 tiles a worker)",
        ),
        connect_timeout_option(),
    )


# What --help says of every scheduler: Dask moves pickles both ways.
TRUSTED = (
    "; the scheduler and its workers are trusted with code execution in this process (Dask sends pickles): "
    "give only a cluster you control, on a private network or over tls://"
)


def scheduler_option(what: str):
    return click.option(
        "--scheduler",
        help=f"{what}, e.g. tls://10.0.0.5:8786 or tcp://10.0.0.5:8786 (default: $RAYBENCH_SCHEDULER){TRUSTED}",
    )


def tls_options():
    """--tls-ca, --tls-cert, --tls-key: this client's credentials for a tls:// scheduler."""
    readable = click.Path(dir_okay=False)  # checked by cluster.client.check_tls, a FIFO included
    config = "(default: Dask's config, distributed.comm.tls."
    return stacked(
        click.option("--tls-ca", type=readable,
                     help=f"--scheduler tls://: the CA certificate (PEM) of the cluster's {config}ca-file)"),
        click.option("--tls-cert", type=readable,
                     help=f"--scheduler tls://: this client's certificate (PEM) {config}client.cert)"),
        click.option("--tls-key", type=readable,
                     help=f"--scheduler tls://: this client's private key (PEM), where --tls-cert's file does not "
                     f"hold it {config}client.key)"),
    )  # fmt: skip


def scheduler_security(scheduler, tls_ca, tls_cert, tls_key):
    """The distributed Security of --tls-ca/--tls-cert/--tls-key for the
    scheduler's address; None (Dask's own config) where none is given."""
    given = {"--tls-ca": tls_ca, "--tls-cert": tls_cert, "--tls-key": tls_key}
    if not any(given.values()):
        return None
    named = ", ".join(name for name, value in given.items() if value)
    if scheduler is None:
        raise RaybenchError(f"{named}: apply to --scheduler tls://... only")
    if not scheduler.startswith("tls://"):
        raise RaybenchError(f"{named}: the scheduler's address must be tls://..., got {scheduler}")
    if not (tls_ca and tls_cert):
        raise RaybenchError("--scheduler tls://: give --tls-ca and --tls-cert (and --tls-key unless the "
                            "certificate's file holds the key) together")  # fmt: skip
    from distributed.security import Security

    from ..cluster.client import check_tls

    check_tls(tls_ca, tls_cert, tls_key, names=("--tls-ca", "--tls-cert", "--tls-key"))
    return Security(require_encryption=True, tls_ca_file=tls_ca, tls_client_cert=tls_cert, tls_client_key=tls_key)


def connect_timeout_option():
    return click.option(
        "--connect-timeout",
        type=float,
        callback=_checked(check_connect_timeout),
        default=10.0,
        show_default=True,
        help="seconds to try the scheduler's address before giving up",
    )


def _checked(check):
    """A click callback that checks an option's value by raybench's own rule
    (the one the Python API applies), as a usage error naming the option."""

    def callback(ctx, param, value):
        if value is None:
            return None
        try:
            return check(value)
        except RaybenchError as exc:
            raise click.BadParameter(str(exc)) from None

    return callback


def open_cluster(workers, device, scheduler, connect_timeout, security=None):
    """The embedded cluster of --workers, or the running one at --scheduler
    (security: scheduler_security's)."""
    from ..cluster import Cluster

    return Cluster(workers=workers, device=device, scheduler=scheduler, timeout=connect_timeout, security=security)
