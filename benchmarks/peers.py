"""raybench's CPU frames against other tracers on the same machine, in one run, side by side:
one subcommand a peer.

    peers.py pymol  [--molecules 1hpv il2 1tii 1tii*2 ...]   PyMOL's `ray` on molecules
    peers.py povray [--scenes balls:3 balls:4 ...]           POV-Ray 3.7 on the SPD's scenes
    peers.py embree [--spheres ...]                          Mitsuba 3 on Embree, the same primary rays
    peers.py embreex [--subdivisions ...]                    Embree 4 through embreex on a triangle mesh, the same rays
    peers.py mitsuba [--variant ... --device ...]            Mitsuba 3 (Embree, OptiX) on a triangle mesh, the same rays

Each side is timed warm (its first frames left out), in --rounds rounds of --frames frames, the
sides alternating which goes first each round, each side's turn after --settle seconds idle, so
that a neighbour's load falls on both; medians over every frame of a side. Records of the results
schema's "parts" suite: raybench's frames (quantity "frame", option "peer") and the peer's
("pymol-ray", "povray-render", "embree-intersect", "embreex-intersect", "mitsuba-intersect" and
"mitsuba-frame"), the peer's with its time over raybench's.

pymol: the peer runs in a process of its own (_pymol_worker.py, by the Python that has PyMOL:
Debian's `pymol` package, /usr/bin/python3), given the molecule file raybench reads, shown as
spheres with raybench's radii and colours, the view set to raybench's fitted camera (the same
eye, look-at point, up and vertical field of view: pymol_view; --zoom brings both eyes that many
times nearer, the molecule then filling more of the frame), one light with shadows in
the direction of raybench's point light, no head-on light, no specular, no depth cue or fog,
antialias off, a black background (raybench's molecules are on black too), max_threads
equal to raybench's threads. What the two pictures share is measured and recorded: the
share of pixels where both or neither show an atom (the silhouette) and the mean difference
of the colours where both do. PyMOL's `ray` sets up its primitives and its grid each call; raybench's
frame walks a tree built once (its build is recorded beside it).

A molecule is a name from PyMOL's data (pymol-data's demo and tut folders) or a path, with
`*K` for K copies of it side by side (written by gemmi into a temporary PDB file that both
sides read): PyMOL's data has no molecule of 10,000 atoms.

povray: each SPD scene at a size factor (raybench.formats.spd), written as a .pov file by
raybench.formats.pov (the same camera, lights, materials, depth), rendered by `povray` at
--size with -A (no antialiasing) and +WT (its threads, raybench's), no file written while
timed; its time is the process's wall time (parse, bounding, trace), and POV-Ray's own parse,
bounding and trace times are recorded beside it. Both render the whole scene: its polygons and
patches as the same triangles, its cones as POV-Ray's own (raybench tessellates them,
raybench.formats.polygons: the peer's best form of the scene). The pictures are compared: the
silhouette, and the mean difference of the colours over the whole picture.
"""

from __future__ import annotations

import argparse
import json
import math
import re
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import _embree
import _embreex
import _harness
import _mitsuba
import numpy as np

from raybench import Camera, Renderer
from raybench.backends.cpu import default_threads
from raybench.scene import Scene

PYMOL_PYTHON = "/usr/bin/python3"
PYMOL_DATA = (Path("/usr/share/pymol/data/demo"), Path("/usr/share/pymol/data/tut"))
MOLECULES = ["1hpv", "il2", "1tii", "1tii*2", "1tii*4"]
# Room between copies of a molecule, in angstroms: none of their atoms touch.
COPY_GAP = 4.0


def molecule_file(spec: str, folder: Path) -> tuple[str, Path]:
    """(name, path) of a --molecules entry: NAME or PATH, with *K for K copies in a grid."""
    base, _, copies = spec.partition("*")
    path = Path(base)
    if not path.is_file():
        found = [d / f"{base}.pdb" for d in PYMOL_DATA if (d / f"{base}.pdb").is_file()]
        if not found:
            raise SystemExit(f"--molecules: {base}: no such file, nor {base}.pdb in {PYMOL_DATA[0].parent}")
        path = found[0]
    k = int(copies or 1)
    if k == 1:
        return base, path
    import gemmi

    structure = gemmi.read_structure(str(path))
    structure.remove_alternative_conformations()
    structure.remove_waters()
    model = structure[0]
    xyz = np.array([a.pos.tolist() for ch in model for r in ch for a in r])
    step = xyz.max(axis=0) - xyz.min(axis=0) + COPY_GAP
    columns = math.ceil(math.sqrt(k))
    chains = [ch.clone() for ch in model]
    names = iter("ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789")
    while len(model):
        model.remove_chain(model[0].name)
    for c in range(k):
        shift = gemmi.Position(step[0] * (c % columns), step[1] * (c // columns), 0.0)
        for chain in chains:
            copy = chain.clone()
            copy.name = next(names)
            for residue in copy:
                for atom in residue:
                    atom.pos = atom.pos + shift
            model.add_chain(copy)
    out = folder / f"{base}-x{k}.pdb"
    structure.write_pdb(str(out))
    return f"{base} x{k}", out


def pymol_view(camera, centers: np.ndarray, radii: np.ndarray) -> tuple[list, list]:
    """PyMOL's 18-number view of a raybench Camera, and a direction in PyMOL's camera space:
    the rotation from the model's axes to the camera's (x right, y up, looking down -z), column
    by column; the eye's place from the origin of rotation, (0, 0, -distance); that origin, the
    look-at point; the clipping planes, clear of every sphere; and -fov (perspective, PyMOL's
    field_of_view, the vertical one as raybench's)."""
    eye, at, up = (np.array(v, np.float64) for v in (camera.position, camera.look_at, camera.up))
    forward = (at - eye) / np.linalg.norm(at - eye)
    right = np.cross(forward, up)
    right /= np.linalg.norm(right)
    rotation = np.array([right, np.cross(right, forward), -forward])
    distance = float(np.linalg.norm(at - eye))
    reach = float((np.linalg.norm(centers - at, axis=1) + radii).max())
    front = max(distance - reach - 1.0, 0.01 * distance)
    view = [*rotation.T.ravel().tolist(), 0.0, 0.0, -distance, *at.tolist(), front, distance + reach + 1.0,
            -camera.fov_deg]  # fmt: skip
    return view, rotation


class PyMOL:
    """The worker process: requests and answers as _pymol_worker.py gives them."""

    def __init__(self):
        worker = Path(__file__).with_name("_pymol_worker.py")
        self.process = subprocess.Popen([PYMOL_PYTHON, str(worker)], stdin=subprocess.PIPE, stdout=subprocess.PIPE,
                                        text=True)  # fmt: skip

    def ask(self, **request) -> dict:
        self.process.stdin.write(json.dumps(request) + "\n")
        self.process.stdin.flush()
        line = self.process.stdout.readline()
        if not line:
            raise SystemExit(f"pymol: its worker ended (exit {self.process.wait()})")
        return json.loads(line)

    def close(self) -> None:
        self.process.stdin.write('{"quit": true}\n')
        self.process.stdin.close()
        self.process.wait()


def black(scene: Scene, zoom: float = 1.0) -> Scene:
    """The scene on black, PyMOL's background (raybench's molecule is on black too; a scene of
    another source may not be), its eye zoom times nearer the look-at point (raybench's fitted
    view leaves most of the frame empty; a PyMOL user zooms in)."""
    camera = scene.camera
    if zoom != 1.0:
        eye, at = np.array(camera.position), np.array(camera.look_at)
        camera = Camera(position=tuple((at + (eye - at) / zoom).tolist()), look_at=camera.look_at, up=camera.up,
                        fov_deg=camera.fov_deg)  # fmt: skip
    return Scene(scene.centers, scene.radii, scene.colors, camera, materials=scene.materials,
                 lights=scene.lights, ambient=scene.ambient, background=(0.0, 0.0, 0.0))  # fmt: skip


def agreement(ours: np.ndarray, hits: np.ndarray, theirs: np.ndarray) -> dict:
    """How alike the two pictures are: the share of pixels where both or neither show the
    molecule, and the mean absolute difference (of 255) of the channels where both do."""
    shown = theirs.max(axis=2) > 0
    hit = hits >= 0
    both = hit & shown
    diff = np.abs(ours.astype(np.int16) - theirs.astype(np.int16))[both]
    return {
        "silhouette_agree": float(np.mean(hit == shown)),
        "mean_abs_diff": float(diff.mean()) if both.any() else None,
    }


def side_by_side(path: Path, left: np.ndarray, right: np.ndarray) -> None:
    """The two pictures at half size, raybench's on the left."""
    from PIL import Image

    halves = [
        Image.fromarray(a).resize((a.shape[1] // 2, a.shape[0] // 2), Image.Resampling.BOX) for a in (left, right)
    ]
    out = Image.new("RGB", (halves[0].width * 2, halves[0].height))
    out.paste(halves[0], (0, 0))
    out.paste(halves[1], (halves[0].width, 0))
    path.parent.mkdir(parents=True, exist_ok=True)
    out.save(path)


def turn(settle: float, call, frames: int):
    time.sleep(settle)  # the other side's idle threads asleep again: they spin a while after its work
    return call(frames)


def pymol_one(spec, folder, width, height, threads, args, pymol) -> list[dict]:
    """raybench's frames and PyMOL's rays of one molecule, alternating."""
    from PIL import Image

    from raybench.formats import molecule

    name, path = molecule_file(spec, folder)
    scene = black(molecule.load(path), args.zoom)
    n = len(scene)
    view, rotation = pymol_view(scene.camera, scene.centers, scene.radii)
    at = np.array(scene.camera.look_at)
    light = at - np.array(scene.lights[0].position)
    positions, elements = molecule.atoms(path)
    atoms = {e: [molecule.radius(e), list(molecule.colour(e))] for e in set(elements)}
    settings = {"ray_shadows": 1, "antialias": 0, "max_threads": threads, "depth_cue": 0, "ray_trace_fog": 0,
                "fog": 0, "orthoscopic": 0, "light_count": 2, "light": (rotation @ light).tolist(), "direct": 0.0,
                "reflect": float(scene.lights[0].intensity), "ambient": float(scene.ambient[0]), "specular": 0.0,
                "bg_rgb": [0.0, 0.0, 0.0], "ray_opaque_background": 1}  # fmt: skip
    loaded = pymol.ask(load=str(path), atoms=atoms, settings=settings, view=view)
    if loaded["atoms"] != n:
        raise SystemExit(f"pymol: {name}: PyMOL shows {loaded['atoms']} atoms, raybench {n}")

    renderer = Renderer(scene, width, height, device="cpu", shading="whitted", threads=threads)
    try:
        compile_s = renderer.compile()
        start = time.perf_counter()
        frame = renderer.render()
        our_first = time.perf_counter() - start
        start = time.perf_counter()
        pymol.ask(ray=[width, height], times=1)
        their_first = time.perf_counter() - start
        picture = folder / f"{name.replace(' ', '-')}-pymol.png"
        pymol.ask(png=str(picture))
        theirs_image = np.asarray(Image.open(picture).convert("RGB"))
        alike = agreement(frame.image, frame.hits, theirs_image)
        if args.pictures:
            shown = f"{name.replace(' ', '-')}" + (f"-zoom{args.zoom:g}" if args.zoom != 1.0 else "")
            side_by_side(Path(args.pictures) / f"{shown}.png", frame.image, theirs_image)
        for _ in range(args.warmup):
            renderer.render(hits=False)
            pymol.ask(ray=[width, height], times=1)

        def ours(frames):
            return _harness.timings(lambda: renderer.render(hits=False), frames)

        def theirs(frames):
            return pymol.ask(ray=[width, height], times=frames)["ms"]

        sides = {"raybench": lambda: turn(args.settle, ours, args.frames),
                 "pymol": lambda: turn(args.settle, theirs, args.frames)}  # fmt: skip
        times = _harness.paired(sides, args.rounds)
        build_s = renderer.tracer.build_s
    finally:
        renderer.close()
    options = {"peer": "pymol", "scene": name, "accel": "bvh", "threads": threads, "shading": "whitted",
               "depth": 5, "shadow_samples": 1, "zoom": args.zoom}  # fmt: skip
    rays = frame.rays or {}
    ours_values = {"build_s": build_s, "compile_s": compile_s, "first_frame_s": our_first,
                   "rays_per_frame": float(sum(rays.values())) if rays else None}  # fmt: skip
    ours_record = _harness.part("frame", "cpu", times["raybench"], spheres=n, width=width, height=height,
                                options=options, values=ours_values)  # fmt: skip
    over = _harness.median(times["pymol"]) / _harness.median(times["raybench"])
    covered = float(np.mean(frame.hits >= 0))
    theirs_values = {"over_raybench": over, "first_ray_s": their_first, "covered": covered, **alike}
    theirs_options = {"scene": name, "max_threads": threads, "pymol": loaded["pymol"], "shadows": True,
                      "antialias": 0, "zoom": args.zoom}  # fmt: skip
    theirs_record = _harness.part("pymol-ray", "cpu", times["pymol"], spheres=n, width=width, height=height,
                                  options=theirs_options, values=theirs_values)  # fmt: skip
    return [ours_record, theirs_record]


def pymol_run(args) -> int:
    width, height = (int(v) for v in args.size.split("x"))
    threads = args.threads or default_threads()
    settings = {"peer": "pymol", "note": args.note, "settle_s": args.settle, "pymol_python": PYMOL_PYTHON}
    pymol = PyMOL()
    try:
        with tempfile.TemporaryDirectory() as tmp, _harness.Records("peers", args, settings) as out:
            for spec in args.molecules:
                for record in pymol_one(spec, Path(tmp), width, height, threads, args, pymol):
                    out.write(record)
    finally:
        pymol.close()
    return 0


def povray_times(stderr: str) -> dict:
    """POV-Ray's own seconds of parse, bounding and trace, from its statistics."""
    found = {}
    for key in ("Parse", "Bounding", "Trace"):
        m = re.search(rf"{key} Time:.*?\(([0-9.]+) seconds\)", stderr)
        found[f"{key.lower()}_s"] = float(m[1]) if m else None
    return found


def povray_one(spec, folder, width, height, threads, args) -> list[dict]:
    """raybench's frames and POV-Ray's renders (whole, and spheres only) of one SPD scene."""
    from PIL import Image

    from raybench.formats import pov, spd

    name, _, size = spec.partition(":")
    nff = spd.generate(name, int(size) if size else None)
    scene = nff.scene()
    label = f"{name} {size or spd.SCENES[name][1]}"
    counts = nff.counts()
    variants = {"whole": folder / f"{name}{size}.pov"}
    pov.save(variants["whole"], pov.from_nff(nff, width, height, args.depth))
    picture = folder / "povray.png"

    def render(path, out=None):
        argv = pov.command(path, width, height, threads) + ([f"+O{out}"] if out else ["-F"])
        start = time.perf_counter()
        done = subprocess.run(argv, capture_output=True, text=True, cwd=folder)
        elapsed = (time.perf_counter() - start) * 1e3
        if done.returncode != 0:
            raise SystemExit(f"povray: {path.name}: exit {done.returncode}: {done.stderr.strip().splitlines()[-1:]}")
        return elapsed, povray_times(done.stderr)

    own = {key: [] for key in variants}
    given = {"threads": threads} if args.device == "cpu" else {}  # POV-Ray's threads either way
    renderer = Renderer(scene, width, height, device=args.device, shading="whitted", depth=args.depth, **given)
    try:
        compile_s = renderer.compile()
        start = time.perf_counter()
        frame = renderer.render()
        our_first = time.perf_counter() - start
        render(variants["whole"], picture)
        theirs_image = np.asarray(Image.open(picture).convert("RGB"))
        shown = (theirs_image != np.round(np.asarray(scene.background) * 255)).any(axis=2)
        diff = np.abs(frame.image.astype(np.int16) - theirs_image.astype(np.int16))
        alike = {"silhouette_agree": float(np.mean(shown == (frame.hits >= 0))), "mean_abs_diff": float(diff.mean())}
        if args.pictures:
            side_by_side(Path(args.pictures) / f"{name}-{size}.png", frame.image, theirs_image)

        def theirs(key):
            def run(frames):
                out = []
                for _ in range(frames):
                    elapsed, parts = render(variants[key])
                    out.append(elapsed)
                    own[key].append(parts)
                return out

            return run

        def ours(frames):
            return _harness.timings(lambda: renderer.render(hits=False), frames)

        sides = {"raybench": lambda: turn(args.settle, ours, args.frames)}
        for key in variants:
            sides[key] = lambda key=key: turn(args.settle, theirs(key), args.frames)
        times = _harness.paired(sides, args.rounds)
        build_s = renderer.tracer.build_s
    finally:
        renderer.close()
    ours_median = _harness.median(times["raybench"])
    rays = frame.rays or {}
    options = {"peer": "povray", "scene": label, "content": "whole", "accel": "bvh", "shading": "whitted",
               "depth": args.depth, **({"threads": threads} if args.device == "cpu" else {})}  # fmt: skip
    ours_values = {"build_s": build_s, "compile_s": compile_s, "first_frame_s": our_first,
                   "rays_per_frame": float(sum(rays.values())) if rays else None,
                   "triangles": float(0 if scene.triangles is None else scene.triangles.shape[1]),
                   "cones_tessellated": float(counts["cones"])}  # fmt: skip
    records = [_harness.part("frame", args.device, times["raybench"], spheres=len(scene), width=width, height=height,
                             options=options, values=ours_values)]  # fmt: skip
    for key in variants:
        parts = {k: _harness.median([p[k] for p in own[key] if p[k] is not None] or [math.nan]) for k in own[key][0]}
        values = {
            "over_raybench": _harness.median(times[key]) / ours_median,
            "trace_over_raybench": parts["trace_s"] * 1e3 / ours_median,
            **parts,
            **alike,
        }
        their_options = {"scene": label, "content": key,
                         "threads": threads, "antialias": 0, "max_trace_level": args.depth + 1}  # fmt: skip
        records.append(_harness.part("povray-render", "cpu", times[key], spheres=len(scene), width=width,
                                     height=height, options=their_options, values=values))  # fmt: skip
    return records


def povray_run(args) -> int:
    width, height = (int(v) for v in args.size.split("x"))
    threads = args.threads or default_threads()
    version = subprocess.run(["povray", "--version"], capture_output=True, text=True).stderr
    version = next((line for line in version.splitlines() if line.startswith("POV-Ray")), "unknown")
    settings = {"peer": "povray", "note": args.note, "settle_s": args.settle, "povray": version}
    with tempfile.TemporaryDirectory() as tmp, _harness.Records("peers", args, settings) as out:
        for spec in args.scenes:
            for record in povray_one(spec, Path(tmp), width, height, threads, args):
                out.write(record)
    return 0


def common(p, frames: int, rounds: int) -> None:
    _harness.add_common(p, frames=frames, rounds=rounds)
    p.add_argument("--note", default="", help="a note kept in the run's settings, e.g. the machine's state")


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    peers = parser.add_subparsers(dest="peer", required=True)
    embree = peers.add_parser("embree", help="Mitsuba 3 on Embree: the same primary rays (run with Mitsuba's Python)")
    _embree.add_arguments(embree)
    _harness.add_common(embree, frames=3, rounds=7)
    embreex = peers.add_parser("embreex", help="Embree 4 through embreex: a triangle mesh, the same primary rays")
    _embreex.add_arguments(embreex)
    _harness.add_common(embreex, frames=3, rounds=5)
    mitsuba = peers.add_parser("mitsuba", help="Mitsuba 3 (LLVM: Embree; cuda: OptiX): a triangle mesh, the same rays")
    _mitsuba.add_arguments(mitsuba)
    _harness.add_common(mitsuba, frames=5, rounds=5)
    pymol = peers.add_parser("pymol", help="PyMOL's ray on molecules")
    pymol.add_argument("--molecules", nargs="+", default=MOLECULES, help="names in PyMOL's data or paths, *K: K copies")
    pymol.add_argument("--size", default="1680x1050")
    pymol.add_argument("--threads", type=int, help="raybench's threads and PyMOL's max_threads (default: every core)")
    pymol.add_argument("--warmup", type=int, default=1, help="frames a side after the first, untimed")
    pymol.add_argument("--settle", type=float, default=0.3, help="seconds idle before each side's turn")
    pymol.add_argument("--pictures", help="a folder for each molecule's two pictures side by side (PNG)")
    pymol.add_argument("--zoom", type=float, default=1.0, help="the eye that many times nearer than raybench's fit")
    common(pymol, frames=2, rounds=5)
    povray = peers.add_parser("povray", help="POV-Ray 3.7 on the SPD's scenes")
    povray.add_argument("--scenes", nargs="+", default=["balls:3", "balls:4"], help="SPD NAME:SIZE, e.g. balls:4")
    povray.add_argument("--size", default="1680x1050")
    povray.add_argument("--depth", type=int, default=5, help="Whitted's bounces (POV-Ray's max_trace_level - 1)")
    povray.add_argument("--threads", type=int, help="raybench's threads and POV-Ray's +WT (default: every core)")
    povray.add_argument("--device", choices=["cpu", "cuda", "wgpu"], default="cpu",
                        help="raybench's device (default cpu); POV-Ray runs on the host's cores")  # fmt: skip
    povray.add_argument("--settle", type=float, default=0.3, help="seconds idle before each side's turn")
    povray.add_argument("--pictures", help="a folder for each scene's two pictures side by side (PNG)")
    common(povray, frames=1, rounds=5)
    args = parser.parse_args()
    _harness.check_common(parser, args)
    if getattr(args, "zoom", 1.0) <= 0:
        parser.error(f"--zoom: must be above 0, got {args.zoom}")
    if args.label is None:
        args.label = f"peers-{args.peer}"
    if args.peer == "embree":
        return _embree.run(args)
    if args.peer == "embreex":
        return _embreex.run(args)
    if args.peer == "mitsuba":
        return _mitsuba.run(args)
    return pymol_run(args) if args.peer == "pymol" else povray_run(args)


if __name__ == "__main__":
    sys.exit(main())
