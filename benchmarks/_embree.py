"""`peers.py embree`: raybench's CPU BVH walk against Mitsuba 3 on Embree, side by side, on the
same rays. Until 2026-12-03 this was benchmarks/embree_side_by_side.py, with the
same flags; docs/notes/embree.md's commands name it so.

Mitsuba is no raybench dependency: run this with a Python that has both,
for example a venv of its own with raybench's pinned numpy and numba:

    python3 -m venv /work/venv-mitsuba
    /work/venv-mitsuba/bin/pip install mitsuba numpy==2.4.6 numba==0.68.1 \\
        psutil py-cpuinfo click rich pillow
    PYTHONPATH=src /work/venv-mitsuba/bin/python benchmarks/peers.py embree --out embree.jsonl

What each side does, a frame:
- raybench: a whole frame of the CPU backend through its BVH (Tracer.trace:
  the primary rays made, walked, the hits shaded into the picture), on every
  usable core;
- Mitsuba (variant llvm_ad_rgb, whose ray tracing is Embree's):
  Scene.ray_intersect_preliminary on the same primary rays, made beforehand
  as NumPy float32 arrays exactly as raybench's kernel makes them
  (kernels.trace.primary_ray) and held evaluated in Dr.Jit: the closest hit
  (t, which sphere) and nothing else, no shading, with coherent=True (the rays
  are a camera's), on Dr.Jit's thread pool (every core by default).
Mitsuba is given less work than raybench, so a ratio in raybench's favour
is not flattered.

The spheres: every sphere its own Mitsuba `sphere` shape (the exact sphere
test of Embree user geometry, which is how Mitsuba traces a sphere); its
scene loads slowly (minutes at 100,000 spheres on 2 cores), so past
--max-shapes spheres it uses one `ellipsoids` shape of all of them instead
(scale r on every axis, extent 1: the same spheres, an ellipsoid's test),
measured beside the spheres at --both-at spheres so the two can be compared.

Before any timing, each side's hit sphere of every ray is compared: the
record gives the share of rays that agree (misses included), so a ratio is
of the same work.

Timing: warm frames on both sides (compiled, a first frame and warm-up
frames left out), then --rounds rounds of --frames frames a side, the two
sides alternating which goes first each round, so that a neighbour's load on
a shared machine falls on both; medians over every frame of a side. Each
side's frames of a round begin after --settle seconds idle: a thread pool
spins a while after its work before it sleeps, and without the pause
raybench's frames right after Mitsuba's were slower than after its own
(docs/notes/embree.md#against-mitsuba-3-on-embree-side-by-side-2-vcpu-machine).

Records of the results schema per (layout, spheres, Mitsuba's shape): raybench's frames a point
of its "scaling" suite (accel "bvh", option layout), Mitsuba's intersections a record of its
"parts" suite (quantity "embree-intersect", options naming the shape and the variant, with the
share of hits that agree, Mitsuba over raybench, and its scene's load and first frame).
"""

from __future__ import annotations

import time

import _harness
import numpy as np

import raybench
from raybench import Camera, backends
from raybench.backends.cpu import default_threads
from raybench.scene import SPREADS


def primary_rays(basis: np.ndarray, width: int, height: int):
    """The unit directions of every pixel's ray, row by row, in float32
    exactly as kernels.trace.primary_ray computes them (IEEE float32 each
    step, no fused multiply-add)."""
    f32 = np.float32
    half, one = f32(0.5), f32(1.0)
    x = np.arange(width, dtype=f32)[None, :]
    y = np.arange(height, dtype=f32)[:, None]
    u = np.broadcast_to((x + half) / f32(width) - half, (height, width))
    v = np.broadcast_to(half - (y + half) / f32(height), (height, width))
    d = [basis[1, a] + basis[2, a] * u + basis[3, a] * v for a in range(3)]
    inv = one / np.sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2])
    return [np.ascontiguousarray((c * inv).astype(f32).ravel()) for c in d]


def mitsuba_rays(mi, dr, basis: np.ndarray, width: int, height: int):
    """raybench's primary rays (primary_rays) as a Mitsuba Ray3f of the variant set, evaluated
    and waited for: held in the variant's memory (a GPU's for cuda) before any frame is timed."""
    rays = width * height
    dx, dy, dz = primary_rays(basis, width, height)
    o = basis[0]
    ray = mi.Ray3f(
        mi.Point3f(mi.Float(np.full(rays, o[0], np.float32)), mi.Float(np.full(rays, o[1], np.float32)),
                   mi.Float(np.full(rays, o[2], np.float32))),
        mi.Vector3f(mi.Float(dx), mi.Float(dy), mi.Float(dz)),
    )  # fmt: skip
    dr.eval(ray)
    dr.sync_thread()
    return ray


def mitsuba_scene(mi, spheres: np.ndarray, shape: str):
    """The spheres as a Mitsuba scene: one `sphere` shape each (keys in index
    order, so a hit's shape_index is the sphere's index) or one `ellipsoids`
    shape (prim_index)."""
    n = spheres.shape[1]
    if shape == "sphere":
        doc = {"type": "scene"}
        for i in range(n):
            doc[f"s{i:08d}"] = {
                "type": "sphere",
                "center": [float(spheres[0, i]), float(spheres[1, i]), float(spheres[2, i])],
                "radius": float(spheres[3, i]),
            }
        return mi.load_dict(doc)
    r = spheres[3][:, None]
    quaternions = np.zeros((n, 4), np.float32)
    quaternions[:, 3] = 1.0
    return mi.load_dict(
        {
            "type": "scene",
            "e": {
                "type": "ellipsoids",
                "centers": mi.TensorXf(np.ascontiguousarray(spheres[0:3].T)),
                "scales": mi.TensorXf(np.ascontiguousarray(np.repeat(r, 3, axis=1))),
                "quaternions": mi.TensorXf(quaternions),
                "extent": 1.0,
            },
        }
    )


def compare(layout, n, shape, width, height, args, mi, dr) -> list[dict]:
    """Two records: raybench's frames and Mitsuba's intersections of one scene (args: the
    command's --rounds, --frames, --warmup, --settle and --seed)."""
    rounds, frames, warmup, settle, seed = args.rounds, args.frames, args.warmup, args.settle, args.seed
    scene = raybench.random_spheres(n, seed, layout=layout)
    basis = Camera().basis(width, height)
    rays = width * height

    start = time.perf_counter()
    tracer = backends.tracer("cpu", scene.spheres, width, height, accel="bvh")
    make_s = time.perf_counter() - start
    start = time.perf_counter()
    ms = mitsuba_scene(mi, scene.spheres, shape)
    load_s = time.perf_counter() - start
    ray = mitsuba_rays(mi, dr, basis, width, height)

    def ours():
        tracer.trace(basis)

    def theirs():
        pi = ms.ray_intersect_preliminary(ray, coherent=True)
        index = pi.shape_index if shape == "sphere" else pi.prim_index
        dr.eval(pi.t, index)
        dr.sync_thread()
        return pi.t, index

    try:
        # the first frames: compiled, and the hits of each compared
        start = time.perf_counter()
        ours()
        our_first = time.perf_counter() - start
        start = time.perf_counter()
        t, index = theirs()
        their_first = time.perf_counter() - start
        t = np.asarray(t)
        their_hits = np.where(np.isfinite(t), np.asarray(index).astype(np.int64), -1)
        our_hits = tracer.hits.ravel().astype(np.int64)
        agree = float(np.mean(our_hits == their_hits))
        for _ in range(warmup):
            ours()
            theirs()

        def turn(side):
            time.sleep(settle)  # the other side's idle threads asleep again: they spin a while after its work
            return _harness.timings(side, frames)

        times = _harness.paired({"raybench": lambda: turn(ours), "mitsuba": lambda: turn(theirs)}, rounds)
    finally:
        tracer.close()
    options = {"accel": "bvh", "threads": default_threads(), "seed": seed}
    if layout != "even":
        options["layout"] = layout
    ours_record = _harness.point("scaling", "cpu", width, height, n, options, times["raybench"],
                                 first_frame_s=our_first, build_s=tracer.build_s)  # fmt: skip
    ours_record["tracer_s"] = make_s
    values = {
        "hits_agree": agree,
        "rays_hit": float(np.mean(our_hits >= 0)),
        "over_raybench": _harness.median(times["mitsuba"]) / _harness.median(times["raybench"]),
        "rays_per_s": rays / (_harness.median(times["mitsuba"]) / 1e3),
        "load_s": load_s,
        "first_frame_s": their_first,
    }
    theirs_options = {"layout": layout, "shape": shape, "variant": mi.variant(), "threads": dr.thread_count(),
                      "seed": seed}  # fmt: skip
    theirs_record = _harness.part("embree-intersect", "cpu", times["mitsuba"], spheres=n, width=width, height=height,
                                  options=theirs_options, values=values)  # fmt: skip
    return [ours_record, theirs_record]


def add_arguments(p) -> None:
    """The embree subcommand's flags (peers.py adds --frames, --rounds, --label and --out)."""
    p.add_argument("--spheres", type=int, nargs="+", default=[1000, 10_000, 100_000])
    p.add_argument("--layouts", nargs="+", default=list(SPREADS), choices=SPREADS)
    p.add_argument("--size", default="1680x1050")
    p.add_argument("--warmup", type=int, default=2, help="frames a side after the first, untimed")
    p.add_argument(
        "--settle",
        type=float,
        default=0.3,
        help="seconds idle before each side's frames of a round (0: none, as before 2026-12-01): the side "
        "that ran last keeps its threads spinning a while, slowing the other's next frames (docs/notes/embree.md)",
    )
    p.add_argument("--seed", type=int, default=0)
    p.add_argument(
        "--max-shapes",
        type=int,
        default=100_000,
        help="past this many spheres, Mitsuba gets one ellipsoids shape instead of a sphere shape each",
    )
    p.add_argument(
        "--both-at", type=int, nargs="*", default=[10_000], help="sphere counts measured with both Mitsuba shapes"
    )
    p.add_argument("--note", default="", help="a note kept in the run's settings, e.g. the machine's state")


def run(args) -> int:
    width, height = (int(v) for v in args.size.split("x"))

    import drjit as dr
    import mitsuba as mi

    mi.set_variant("llvm_ad_rgb")
    settings = {"peer": "embree", "mitsuba": mi.__version__, "drjit": dr.__version__, "note": args.note,
                "settle_s": args.settle}  # fmt: skip
    with _harness.Records("peers", args, settings) as out:
        for n in args.spheres:
            for layout in args.layouts:
                shapes = ["sphere"] if n <= args.max_shapes else ["ellipsoids"]
                if n in args.both_at:
                    shapes = ["sphere", "ellipsoids"]
                for shape in shapes:
                    for record in compare(layout, n, shape, width, height, args, mi, dr):
                        out.write(record)
    return 0
