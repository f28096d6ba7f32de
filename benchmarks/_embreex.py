"""`peers.py embreex`: raybench's CPU frames of a triangle mesh against Embree 4 through
`embreex`, side by side, on the same rays.

embreex is no raybench dependency: install it beside raybench (a cp311 wheel has Embree 4; for
cp312 PyPI has Embree 2's only), for example into a folder of its own:

    pip install --no-deps --target /tmp/embreex-site embreex
    PYTHONPATH=/tmp/embreex-site:src python benchmarks/peers.py embreex --out embreex.jsonl

The mesh: `trimesh.creation.icosphere` of radius 1 at each --subdivisions, seen from (0, 0,
--distance) looking at its centre, a 60 degree field of view, at --size (the triangle issue's setup
on the 2-vCPU machine, eye at -3).

What each side does, a frame:
- raybench: a whole frame of the cpu backend through its BVH (Tracer.trace with the triangle
  primitive: the primary rays made, walked as 4-wide packets, the hits shaded into the picture),
  on every usable core;
- embreex: EmbreeScene.run on the same primary rays, made beforehand as float32 arrays exactly
  as raybench's kernel makes them (_embree.primary_rays): the closest hit's triangle and nothing
  else (rtcIntersect1 one ray at a time), the rays split into one chunk a thread over
  --threads threads (embreex's loop lets go of Python's lock, so threads run at once; 1 is
  measured too, to show it).
Embree is given less work than raybench, so a ratio in raybench's favour is not flattered.

Before any timing each side's hit triangle of every ray is compared: the record gives the share
of rays that agree (misses included), so a ratio is of the same work. Timing as `peers.py
embree`: warm frames, --rounds rounds of --frames frames a side, the sides alternating which
goes first, each turn after --settle seconds idle; medians over every frame of a side.

Records of the results schema's "parts" suite: raybench's frames (quantity "frame", options
primitive "triangle", triangles, peer "embreex") and embreex's ("embreex-intersect", with its
threads and, in values, its time over raybench's, its rays a second and the hits that agree).
"""

from __future__ import annotations

import time
from concurrent.futures import ThreadPoolExecutor

import _harness
import numpy as np
from _embree import primary_rays

from raybench import backends
from raybench.backends.cpu import default_threads
from raybench.bench import meshes as suite_meshes
from raybench.camera import Camera
from raybench.meshes import MESH_COLOUR, Mesh, mesh_leaves


def icosphere(subdivisions: int) -> Mesh:
    """The meshes suite's icosphere of radius 1 at that many subdivisions."""
    return suite_meshes.icosphere(20 * 4**subdivisions)


def compare(subdivisions: int, threads: int, width: int, height: int, args) -> list[dict]:
    """Two records: raybench's frames and embreex's intersections of one icosphere."""
    from embreex import rtcore_scene
    from embreex.mesh_construction import TriangleMesh

    mesh = icosphere(subdivisions)
    n = len(mesh)
    camera = Camera(position=(0.0, 0.0, args.distance), look_at=(0.0, 0.0, 0.0), fov_deg=60.0)
    basis = camera.basis(width, height)
    rays = width * height

    start = time.perf_counter()
    tracer = backends.tracer("cpu", mesh_leaves(mesh, MESH_COLOUR), width, height, primitive="triangle")
    make_s = time.perf_counter() - start
    start = time.perf_counter()
    scene = rtcore_scene.EmbreeScene()
    TriangleMesh(scene, mesh.vertices, mesh.faces)
    load_s = time.perf_counter() - start
    directions = np.ascontiguousarray(np.stack(primary_rays(basis, width, height), axis=1))
    origins = np.ascontiguousarray(np.broadcast_to(basis[0].astype(np.float32), (rays, 3)))
    cuts = np.linspace(0, rays, threads + 1).astype(np.int64)
    pool = ThreadPoolExecutor(threads)

    def ours():
        tracer.trace(basis)

    def theirs():
        parts = pool.map(lambda k: scene.run(origins[cuts[k] : cuts[k + 1]], directions[cuts[k] : cuts[k + 1]]),
                         range(threads))  # fmt: skip
        return np.concatenate(list(parts))

    try:
        start = time.perf_counter()
        ours()
        our_first = time.perf_counter() - start
        start = time.perf_counter()
        their_hits = theirs().astype(np.int64)
        their_first = time.perf_counter() - start
        our_hits = tracer.hits.ravel().astype(np.int64)
        agree = float(np.mean(our_hits == their_hits))
        for _ in range(args.warmup):
            ours()
            theirs()

        def turn(side):
            time.sleep(args.settle)  # the other side's idle threads asleep again
            return _harness.timings(side, args.frames)

        times = _harness.paired({"raybench": lambda: turn(ours), "embreex": lambda: turn(theirs)}, args.rounds)
    finally:
        tracer.close()
        pool.shutdown()
    shape = {"primitive": "triangle", "triangles": n, "eye_distance": abs(args.distance)}
    mine = {"first_frame_s": our_first, "tracer_s": make_s, "build_s": tracer.build_s}
    options = {**shape, "peer": "embreex", "threads": default_threads()}
    ours_record = _harness.part("frame", "cpu", times["raybench"], width=width, height=height, options=options,
                                values=mine)  # fmt: skip
    values = {
        "hits_agree": agree,
        "rays_hit": float(np.mean(our_hits >= 0)),
        "over_raybench": _harness.median(times["embreex"]) / _harness.median(times["raybench"]),
        "rays_per_s": rays / (_harness.median(times["embreex"]) / 1e3),
        "raybench_rays_per_s": rays / (_harness.median(times["raybench"]) / 1e3),
        "load_s": load_s,
        "first_frame_s": their_first,
    }
    theirs_record = _harness.part("embreex-intersect", "cpu", times["embreex"], width=width, height=height,
                                  options={**shape, "threads": threads}, values=values)  # fmt: skip
    return [ours_record, theirs_record]


def add_arguments(p) -> None:
    """The embreex subcommand's flags (peers.py adds --frames, --rounds, --label and --out)."""
    p.add_argument("--subdivisions", type=int, nargs="+", default=[6, 8], help="icosphere subdivisions (6: 81,920)")
    p.add_argument("--threads", type=int, nargs="+", help="embreex's threads (default: 1 and every core)")
    p.add_argument("--distance", type=float, default=-3.0, help="the eye's z (default -3)")
    p.add_argument("--size", default="1680x1050")
    p.add_argument("--warmup", type=int, default=2, help="frames a side after the first, untimed")
    p.add_argument("--settle", type=float, default=0.3, help="seconds idle before each side's turn")


def run(args) -> int:
    import embreex

    width, height = (int(v) for v in args.size.split("x"))
    counts = args.threads or sorted({1, default_threads()})
    settings = {"peer": "embreex", "embreex": getattr(embreex, "__version__", None), "settle_s": args.settle}
    with _harness.Records("peers", args, settings) as out:
        for subdivisions in args.subdivisions:
            for threads in counts:
                for record in compare(subdivisions, threads, width, height, args):
                    out.write(record)
    return 0
