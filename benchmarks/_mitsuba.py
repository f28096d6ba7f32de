"""`peers.py mitsuba`: raybench's frames of a triangle mesh against Mitsuba 3, side by side, on
the same rays: its LLVM variant (Embree 3 inside) on the CPU, its cuda variant (OptiX) on an
NVIDIA GPU.

Mitsuba is no raybench dependency: run this with a Python that has both, e.g. Mitsuba and Dr.Jit
installed into a folder of their own beside raybench's environment:

    pip install --no-deps --target /tmp/site-mi mitsuba==3.9.1 drjit==1.5.0
    PYTHONPATH=/tmp/site-mi:src python benchmarks/peers.py mitsuba --out mitsuba.jsonl
    PYTHONPATH=/tmp/site-mi:src python benchmarks/peers.py mitsuba --variant cuda_ad_rgb --device cuda

(`benchmarks/lease_wheels.sh mitsuba` prunes the two wheels to what this needs, for the GPU lease.)

The mesh: `trimesh.creation.icosphere` of radius 1 at each --subdivisions (_embreex.icosphere),
seen from (0, 0, -distance) looking at its centre, a 60 degree field of view, at --size. Mitsuba
loads it through its `ply` plugin, from a binary PLY of the same float32 vertices and faces
written into a temporary folder; that its faces and vertices came in unchanged is checked.

What each side does, a frame:
- raybench: a whole frame of --device through its BVH (the tracer with primitive "triangle":
  the primary rays made, walked, the hits shaded into the picture, the picture and the hits
  copied to the host), timed by wall clock; on a GPU also its kernel alone (CUDA events, wgpu's
  timestamps: Tracer.timed_trace), a "kernel" record of its own.
- Mitsuba, "mitsuba-intersect": Scene.ray_intersect_preliminary(ray, coherent=True) on the same
  primary rays, made beforehand as float32 exactly as raybench's kernel makes them
  (_embree.primary_rays) and held evaluated in the variant's memory (the GPU's for cuda), its t
  and triangle index evaluated and waited for (dr.eval, dr.sync_thread): the closest hit and
  nothing else. Its kernels' own time (Dr.Jit's kernel history, a pass of its own after the
  timed rounds) is in values.kernel_ms.
- Mitsuba, "mitsuba-frame": mi.render(scene, spp=1) of a `perspective` sensor of the same eye,
  field of view and size, whose one sample a pixel is at the pixel's centre (a `stratified`
  sampler, jitter off), through the `aov` integrator with two outputs, the hit's distance and
  its triangle (`depth`, `prim_index`: a full ray_intersect, its surface interaction made), a
  `box` filter into an `hdrfilm`, then the developed float image copied to the host (np.asarray).
  Its rays are the sensor's, not raybench's; their triangles are compared with raybench's too.
Mitsuba's intersection is less work than raybench's frame, so a ratio in raybench's favour is
not flattered.

Before any timing, each side's hit triangle of every ray is compared: values.hits_agree is the
share of rays that agree (misses included). Timing as `peers.py embreex`: warm frames,
--rounds rounds of --frames frames a side, the sides taking turns in an order that turns each
round, each turn after --settle seconds idle; medians over every frame of a side.

Records of the results schema's "parts" suite: raybench's "frame" (options primitive
"triangle", triangles, peer "mitsuba-<variant>") and, on a GPU, its "kernel"; Mitsuba's
"mitsuba-intersect" and "mitsuba-frame" (device cpu for llvm, cuda for cuda), with their time
over raybench's frame (and over its kernel, on a GPU), rays a second and the hits that agree.
"""

from __future__ import annotations

import re
import sys
import tempfile
import time
from pathlib import Path

import _harness
import numpy as np
from _embree import mitsuba_rays
from _embreex import icosphere

from raybench import backends
from raybench.backends.cpu import default_threads
from raybench.camera import Camera
from raybench.meshes import MESH_COLOUR, mesh_leaves

VARIANTS = ("llvm_ad_rgb", "cuda_ad_rgb")
FOV = 60.0


def mitsuba_scene(mi, path: Path, eye: tuple, width: int, height: int):
    """The mesh file as a Mitsuba scene with a sensor for mi.render: raybench's camera (eye,
    looking at the origin, y up, 60 degrees vertically), one sample a pixel at its centre, and an
    integrator whose outputs are the hit's distance and triangle index."""
    sensor = {
        "type": "perspective",
        "fov": FOV,
        "fov_axis": "y",
        "to_world": mi.ScalarTransform4f().look_at(origin=list(eye), target=[0, 0, 0], up=[0, 1, 0]),
        "film": {"type": "hdrfilm", "width": width, "height": height, "rfilter": {"type": "box"},
                 "sample_border": False},
        "sampler": {"type": "stratified", "sample_count": 1, "jitter": False},
    }  # fmt: skip
    return mi.load_dict({
        "type": "scene",
        "mesh": {"type": "ply", "filename": str(path), "face_normals": True},
        "sensor": sensor,
        "integrator": {"type": "aov", "aovs": "dd:depth,pi:prim_index"},
    })  # fmt: skip


def loaded_alike(mesh, shape) -> bool:
    """Mitsuba's mesh has the file's faces in order and its float32 vertices: its triangle
    index is raybench's."""
    faces = np.asarray(shape.faces_buffer()).reshape(-1, 3)
    vertices = np.asarray(shape.vertex_positions_buffer()).reshape(-1, 3)
    return np.array_equal(faces, mesh.faces) and np.array_equal(vertices, mesh.vertices)


def kernel_times(dr, call, times: int) -> list[float]:
    """The milliseconds of the kernels that each of `times` calls launched, summed a call, as
    Dr.Jit's kernel history times them (on CUDA, the GPU's own clock)."""
    dr.set_flag(dr.JitFlag.KernelHistory, True)
    try:
        dr.kernel_history()  # emptied
        out = []
        for _ in range(times):
            call()
            out.append(sum(k.get("execution_time", 0.0) for k in dr.kernel_history()))
        return out
    finally:
        dr.set_flag(dr.JitFlag.KernelHistory, False)


def compare(subdivisions: int, width: int, height: int, args, mi, dr, folder: Path) -> list[dict]:
    """raybench's frames (and kernels, on a GPU), Mitsuba's intersections and frames of one icosphere."""
    import trimesh

    mesh = icosphere(subdivisions)
    n = len(mesh)
    eye = (0.0, 0.0, -args.distance)
    basis = Camera(position=eye, look_at=(0.0, 0.0, 0.0), fov_deg=FOV).basis(width, height)
    rays = width * height
    path = folder / f"icosphere-{subdivisions}.ply"
    trimesh.Trimesh(mesh.vertices, mesh.faces, process=False).export(path, encoding="binary")

    start = time.perf_counter()
    tracer = backends.tracer(args.device, mesh_leaves(mesh, MESH_COLOUR), width, height, primitive="triangle")
    make_s = time.perf_counter() - start
    start = time.perf_counter()
    scene = mitsuba_scene(mi, path, eye, width, height)
    load_s = time.perf_counter() - start
    alike = loaded_alike(mesh, scene.shapes()[0])
    ray = mitsuba_rays(mi, dr, basis, width, height)
    kernel_ms: list[float] = []

    def ours():
        kernel_ms.append(tracer.timed_trace(basis))

    def intersect():
        pi = scene.ray_intersect_preliminary(ray, coherent=True)
        dr.eval(pi.t, pi.prim_index)
        dr.sync_thread()
        return pi

    def frame():
        return np.asarray(mi.render(scene, spp=1))  # (H, W, 2): the film's channels, depth and triangle

    try:
        start = time.perf_counter()
        tracer.timed_trace(basis)
        our_first = time.perf_counter() - start
        our_hits = tracer.hits.ravel().astype(np.int64)
        start = time.perf_counter()
        pi = intersect()
        their_first = time.perf_counter() - start
        t = np.asarray(pi.t)
        their_hits = np.where(np.isfinite(t), np.asarray(pi.prim_index).astype(np.int64), -1)
        start = time.perf_counter()
        image = frame()
        frame_first = time.perf_counter() - start
        frame_hits = np.where(image[..., 0] > 0, np.rint(image[..., 1]), -1).astype(np.int64).ravel()
        for _ in range(args.warmup):
            ours()
            intersect()
            frame()
        kernel_ms.clear()

        def turn(side):
            time.sleep(args.settle)  # the other side's idle threads asleep again
            return _harness.timings(side, args.frames)

        sides = {"raybench": lambda: turn(ours), "intersect": lambda: turn(intersect), "frame": lambda: turn(frame)}
        times = _harness.paired(sides, args.rounds)
        their_kernel = kernel_times(dr, intersect, args.frames)
        frame_kernel = kernel_times(dr, frame, args.frames)
    finally:
        tracer.close()
    ours_ms = _harness.median(times["raybench"])
    kernels = [k for k in kernel_ms if k is not None]
    our_kernel = _harness.median(kernels) if kernels else None
    shape = {"primitive": "triangle", "triangles": n, "eye_distance": args.distance}
    peer = f"mitsuba-{args.variant}"
    ours_values = {"first_frame_s": our_first, "tracer_s": make_s, "build_s": tracer.build_s,
                   "rays_per_s": rays / (ours_ms / 1e3), "kernel_ms": our_kernel}  # fmt: skip
    ours_options = {**shape, "peer": peer, "threads": default_threads() if args.device == "cpu" else None,
                    "walk": tracer.walk, "build": getattr(tracer.options, "build", None)}  # fmt: skip
    records = [_harness.part("frame", args.device, times["raybench"], width=width, height=height,
                             options=ours_options, values=ours_values)]  # fmt: skip
    if kernels:
        records.append(_harness.part("kernel", args.device, kernels, width=width, height=height,
                                     options={**shape, "peer": peer}))  # fmt: skip
    device = "cuda" if args.variant.startswith("cuda") else "cpu"
    options = {**shape, "variant": args.variant, "threads": dr.thread_count() if device == "cpu" else None}
    common = {"load_s": load_s, "mesh_alike": float(alike), "rays_hit": float(np.mean(our_hits >= 0))}
    for quantity, key, hits, first, device_ms in (
        ("mitsuba-intersect", "intersect", their_hits, their_first, their_kernel),
        ("mitsuba-frame", "frame", frame_hits, frame_first, frame_kernel),
    ):
        median = _harness.median(times[key])
        values = {
            "hits_agree": float(np.mean(our_hits == hits)),
            "over_raybench": median / ours_ms,
            "over_raybench_kernel": median / our_kernel if our_kernel else None,
            "rays_per_s": rays / (median / 1e3),
            "kernel_ms": _harness.median(device_ms),
            "first_frame_s": first,
            **common,
        }
        records.append(_harness.part(quantity, device, times[key], width=width, height=height, options=options,
                                     values=values))  # fmt: skip
    return records


def size(text: str) -> tuple[int, int]:
    """WIDTHxHEIGHT, both at least 1, or argparse's one-line error."""
    import argparse

    m = re.fullmatch(r"([1-9][0-9]{0,5})x([1-9][0-9]{0,5})", text)
    if not m:
        raise argparse.ArgumentTypeError(f"WIDTHxHEIGHT, e.g. 1680x1050, got {text!r}")
    return int(m[1]), int(m[2])


def add_arguments(p) -> None:
    """The mitsuba subcommand's flags (peers.py adds --frames, --rounds, --label and --out)."""
    p.add_argument("--subdivisions", type=int, nargs="+", default=[6, 8, 9], choices=range(11), metavar="N",
                   help="icosphere subdivisions, 0 to 10 (6: 81,920 triangles; 8: 1.31 M; 9: 5.24 M)")  # fmt: skip
    p.add_argument("--distance", type=float, default=2.0, help="the eye at (0, 0, -distance) (default 2)")
    p.add_argument("--size", type=size, default=(1680, 1050), help="WIDTHxHEIGHT (default 1680x1050)")
    p.add_argument("--variant", choices=VARIANTS, default="llvm_ad_rgb", help="Mitsuba's (cuda_ad_rgb: OptiX)")
    p.add_argument("--device", choices=backends.DEVICES, default="cpu", help="raybench's (default cpu)")
    p.add_argument("--warmup", type=int, default=2, help="frames a side after the first, untimed")
    p.add_argument("--settle", type=float, default=0.3, help="seconds idle before each side's turn")


def refuse(message: str):
    """One line and exit status 2, no traceback."""
    print(f"peers.py mitsuba: {message}", file=sys.stderr)
    raise SystemExit(2)


def run(args) -> int:
    if not args.distance > 1.0:
        refuse(f"--distance: the eye must be outside the sphere, above 1, got {args.distance}")
    try:
        import drjit as dr
        import mitsuba as mi
    except ImportError as exc:
        refuse(f"Mitsuba 3 is not importable ({exc}); benchmarks/_mitsuba.py says how to install it")
    if args.variant not in mi.variants():
        refuse(f"--variant {args.variant}: this Mitsuba has {', '.join(mi.variants())}")
    try:
        mi.set_variant(args.variant)
    except Exception as exc:  # noqa: BLE001 - Dr.Jit raises its own kinds where a backend (LLVM, CUDA) is missing
        refuse(f"--variant {args.variant}: {str(exc).splitlines()[0] if str(exc) else type(exc).__name__}")
    width, height = args.size
    settings = {"peer": f"mitsuba-{args.variant}", "mitsuba": mi.__version__, "drjit": dr.__version__,
                "settle_s": args.settle}  # fmt: skip
    with tempfile.TemporaryDirectory() as tmp, _harness.Records("peers", args, settings) as out:
        for subdivisions in args.subdivisions:
            for record in compare(subdivisions, width, height, args, mi, dr, Path(tmp)):
                out.write(record)
    return 0
