"""Which points each suite measures.

A Point is one thing to time: a device, a size, a scene of n spheres, and the
device options. The thesis's tests 1 to 6 are the sweep of sphere counts at
three resolutions (1-3 on the GPU, 4-6 on the CPU); test 7 is the ramp.
Those are brute force (accel "none"), as in the thesis; with accel "bvh"
asked for too, the same points are measured through the BVH beside them.
The scaling suite goes past the thesis: 10 to 1,000,000 spheres, brute
force and BVH, brute force stopping where its frames would pass a time cap.
Beside the even spread of random_spheres it measures the BVH on the denser
layouts (random_spheres(n, seed, layout=...): larger overlapping spheres,
clusters, a wide depth range) at 10,000 to 1,000,000 spheres, so that a
tree tuned to the even spread alone shows (docs/notes/bvh-walk.md). Only the BVH: brute
force tests every sphere whatever the layout.

The secondary suite asks whether the GPU's lead holds for secondary rays
(docs/notes/whitted.md): Whitted frames of the materials scene (random_spheres(n, seed,
materials=True): plastic, mirrors and glass, one area light) at depth 5 with
4 shadow samples, at the thesis's three sizes and 1,000, 10,000 and 100,000
spheres, through the BVH and by brute force (the simple kernel's loop, the
only brute force Whitted shading has), on every device asked for. Beside
each Whitted point it measures the same scene, size and way with the
thesis's shading (primary rays only): the baseline its verdict compares the
GPU's lead against, taken in the same run.

Brute force with secondary rays is the costly part: a Whitted frame of the
materials scene casts about 12 rays a pixel, each tested against every
sphere: on 2 busy cores a large frame takes minutes at 1,000 spheres and
hours at 100,000 (docs/notes/whitted.md#whitted-shading-issue-14-secondary-rays);
a GPU takes seconds. What a user would expect is brute force measured wherever
its frames are bearable and every point that is not said so, never silently
dropped. So brute-force points carry a cap, as in the scaling suite: a
point whose frame is predicted (linear in pixels and spheres from the last
point of its series) to take more than SECONDARY_CAP_S is recorded as
skipped with that prediction. A GPU thus runs brute force to 100,000
spheres; a CPU stops before 100,000 (a 2-core machine after 1,000 spheres
at 800x600); the BVH runs every point everywhere.

The multi-gpu suite (docs/notes/scaling.md) measures the throughput of 1..N workers of
an embedded raybench.cluster, each owning a device: on cuda every count of
GPUs up to the machine's, on the cpu 1, 2, 4, ... workers up to the cores,
each worker one thread (a worker is then a fixed share of the machine, as a
GPU is). Two jobs: one large frame in tiles, and an orbit's frames. On a GPU
the issue's sizes: an 8192x8192 frame and 240 frames at 1680x1050, at
100,000 spheres; a CPU's cores would take minutes a frame at those, so on the
cpu the frame is 3360x2100 and the orbit 240 frames at 640x400, at 10,000.
The report sets each count's throughput against linear (N x one worker's).

The dynamic suite (docs/notes/gpu-build.md#spheres-that-move) moves the spheres every frame
(raybench.animate.Orbits, seeded like the scene, DYNAMIC_DT seconds of
motion a frame) and times what a frame then costs: the tree's update (cuda
and wgpu with build "gpu": refitted on the GPU, or rebuilt past the refit
limit; cuda and wgpu with build "host", and cpu: rebuilt on the host and,
on a GPU, uploaded) plus the frame. At 10,000, 100,000 and 1,000,000 spheres at
1680x1050, through the BVH (brute force has no tree to update), cuda and
wgpu once per build (both by default, or those --build names).

The meshes suite (bench/meshes.py) traces triangles: an icosphere and random triangles
from about 10 thousand to 10 million, each with the thesis's shading and Whitted's, through
the BVH on every device asked for. Every point carries a cap: one whose frame is predicted
(by the growth its series has shown so far) past it is recorded as skipped, and so is one
that would not fit in the host's or the device's memory.

`--suite all` includes the secondary suite: all means every suite, and the cap keeps the
suite's brute force within minutes a point, as the scaling suite's keeps
its own; what a 2-core machine spends on it is mostly its BVH frames.

Each suite is declared once, as a Suite in REGISTRY (at the end): its name
and help, the function that makes its points from a Plan, and what the
runner, the results' schema and the report read of it. `bench --suite`'s
choices, `--suite all`, the runner's dispatch, the record suites that
results.check_record takes and the report's sections all come from there,
so a new suite is one Suite and its entry in REGISTRY (and, if its frames
are timed in a new way, that way in runner._timed).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field, replace

from ..backends.options import BUILDS, FAST_MAX_THREADS
from ..errors import RaybenchError
from ..host import usable_cores
from ..scene import RAMP
from . import headline, meshes, scenes

ACCELS = ("bvh", "none")
THESIS_SIZES = ((800, 600), (1280, 800), (1680, 1050))
THESIS_COUNTS = tuple(range(100, 1001, 100))
TUNING_SIZE = (1680, 1050)
TUNING_SPHERES = 1000
BLOCKS = ((2, 2), (4, 4), (8, 8), (16, 16), (32, 32), (32, 8), (8, 32), (64, 4), (128, 2), (256, 1))
CONSTANT_COUNTS = (100, 250, 500, 1000)
RAMP_SIZE = (800, 600)
# Half-decades from 10 to 1,000,000 spheres, at the largest thesis size, and
# the 1,000,000 spheres at 1920x1080.
SCALING_COUNTS = (10, 30, 100, 300, 1000, 3000, 10_000, 30_000, 100_000, 300_000, 1_000_000)
SCALING_SIZE = (1680, 1050)
SCALING_EXTRA = ((1920, 1080), 1_000_000)
QUICK_SCALING_COUNTS = (10, 100, 1000, 10_000)
# The denser layouts of random_spheres (scene.SPREADS but "even"), BVH only:
# nine points a device, each the --duration (10 s by default) and a second
# of warm-up, so about 2 minutes more of the suite on any machine; --quick
# adds three small points (1,000 spheres at 640x400).
SCALING_LAYOUTS = ("dense", "clusters", "deep")
SCALING_LAYOUT_COUNTS = (10_000, 100_000, 1_000_000)
QUICK_SCALING_LAYOUT_COUNTS = (1000,)
QUICK_SCALING_SIZE = (640, 400)
# Brute force is not measured where its frame is predicted (linear in spheres
# and pixels, from the last count measured) to take longer than this.
SCALING_CAP_S = 1.0
QUICK_SCALING_CAP_S = 0.25
SECONDARY_SIZES = THESIS_SIZES
SECONDARY_COUNTS = (1000, 10_000, 100_000)
SECONDARY_DEPTH = 5
SECONDARY_SHADOW_SAMPLES = 4
# A brute-force frame predicted past this is skipped: long enough for a GPU
# at 100,000 spheres, short enough that no point takes more than a few
# minutes (a point times at least 5 frames: the first, warm-up, MIN_FRAMES).
SECONDARY_CAP_S = 30.0
# --quick: one small size, the two smaller counts; brute force is skipped
# where its frame would pass the quick cap (on 2 cores: at 10,000 spheres).
DYNAMIC_COUNTS = (10_000, 100_000, 1_000_000)
DYNAMIC_SIZE = (1680, 1050)
QUICK_DYNAMIC_COUNTS = (1000, 10_000)
QUICK_DYNAMIC_SIZE = (640, 400)
# Seconds of the animation between frames: 60 frames a second's worth.
DYNAMIC_DT = 1 / 60
QUICK_SECONDARY_SIZES = ((160, 100),)
QUICK_SECONDARY_COUNTS = (1000, 10_000)
QUICK_SECONDARY_CAP_S = 1.0
# The multi-gpu suite: (frame size, (orbit size, its frames), spheres) by device kind.
MULTI_GPU = {"cuda": ((8192, 8192), ((1680, 1050), 240), 100_000), "cpu": ((3360, 2100), ((640, 400), 240), 10_000)}
QUICK_MULTI_GPU = ((640, 400), ((160, 100), 24), 1000)
# The headline's points are timed again this many times, afresh, later among their device's
# thesis points (in the middle and at the end): the spread between those passes is what lets
# the headline's interval hold a drift of minutes, which one pass's frames cannot see
# (docs/thesis.md#the-headlines-interval).
HEADLINE_REPEATS = 2


def worker_counts(device: str, cores: int, gpus: int) -> list[int]:
    """The multi-gpu suite's worker counts: every GPU count on cuda; on the
    cpu 1, 2, 4, ... up to the cores (and the cores themselves)."""
    if device == "cuda":
        return list(range(1, max(gpus, 1) + 1))
    counts = [1 << i for i in range(cores.bit_length()) if 1 << i <= cores]
    return counts + ([cores] if counts[-1] != cores else [])


@dataclass(frozen=True)
class Point:
    suite: str
    device: str
    width: int
    height: int
    spheres: int
    options: dict = field(default_factory=dict, hash=False)
    test: int | None = None
    # test7 only: the sphere counts of its frames, one per frame
    ramp: tuple[int, ...] | None = None
    # 0: the point; k: its k-th repeat later in the run (the headline's points: HEADLINE_REPEATS)
    repeat: int = 0

    def describe(self) -> str:
        extra = "".join(f" {k}={_fmt(v)}" for k, v in self.options.items() if k not in ("label", "triangles"))
        label = f" ({self.options['label']})" if "label" in self.options else ""
        what = f"test 7 ramp {self.ramp[0]}..{self.ramp[-1]}" if self.ramp else f"{self.spheres} spheres"
        if "triangles" in self.options:  # the meshes suite's: triangles, not spheres
            what = f"{self.options['triangles']:,} triangles"
        test = f"test {self.test} " if self.test and not self.ramp else ""
        again = f", again ({self.repeat} of {HEADLINE_REPEATS})" if self.repeat else ""
        return f"{self.suite} {test}{self.device} {self.width}x{self.height} {what}{extra}{label}{again}"


def _fmt(value) -> str:
    return "x".join(map(str, value)) if isinstance(value, (list, tuple)) else str(value)


def thread_settings(cores: int, height: int) -> list[tuple[str, int]]:
    """The thesis's CPU tuning: 1 thread, half the cores, all cores, twice the
    cores, and one thread per image row."""
    settings = [
        ("1 thread", 1),
        ("half the cores", max(1, cores // 2)),
        ("all cores", cores),
        ("2x cores", 2 * cores),
        ("one per row", height),
    ]
    seen, out = set(), []
    for label, n in settings:
        if n not in seen:
            seen.add(n)
            out.append((label, n))
    return out


GPUS = ("cuda", "wgpu")


def variants(kernels, accels) -> list[dict]:
    """The options of each way to trace a point: brute force once per kernel
    (accel "none"), then the BVH, each as asked for."""
    out = [{"kernel": k, "accel": "none"} for k in kernels] if "none" in accels else []
    return out + ([{"accel": "bvh"}] if "bvh" in accels else [])


def _runs(ways, devices, wgpu: dict, builds=()) -> list[tuple[dict, str]]:
    """(options, device) for each way and device: cpu and cuda every way; wgpu
    every way it has, with its own options (the adapter named): the BVH, and
    brute force once whatever the kernels asked for, with its one kernel
    (simple). builds: where cuda's and wgpu's trees are built ("host",
    "gpu"), the BVH once for each; none given, the backend's default."""
    out = []
    for way in ways:
        for d in devices:
            if d == "cuda" and way["accel"] == "bvh" and builds:
                out += [({**way, "build": b}, d) for b in builds]
            elif d != "wgpu":
                out.append((dict(way), d))
    if "wgpu" in devices:
        own = []
        for way in ways:
            way = {**way, "kernel": "simple"} if way["accel"] == "none" else dict(way)
            if way not in own:
                own.append(way)
        for way in own:
            if way["accel"] == "bvh" and builds:
                out += [({**way, **wgpu, "build": b}, "wgpu") for b in builds]
            else:
                out.append(({**way, **wgpu}, "wgpu"))
    return out


def secondary_shadings() -> list[dict]:
    """The shading options of the secondary suite's points, the baseline
    first: the thesis's (primary rays), then Whitted's."""
    whitted = {"shading": "whitted", "depth": SECONDARY_DEPTH, "shadow_samples": SECONDARY_SHADOW_SAMPLES}
    return [{"shading": "thesis"}, whitted]


@dataclass(frozen=True)
class Plan:
    """What a suite's points are made from: the devices and ways asked for,
    and the machine's limits (points() makes it once for every suite)."""

    devices: tuple
    quick: bool
    cores: int
    kernels: tuple
    accels: tuple
    wgpu: dict
    max_invocations: int
    gpus: int
    builds: tuple
    # (options, device) of each way asked for, on each device (_runs)
    runs: list


@dataclass(frozen=True)
class Suite:
    """One suite, declared once: what `bench --suite` offers and says of it,
    the points it measures, and what the runner, the results' schema and the
    report need to know about its records. Adding a suite is one of these and
    its name in REGISTRY."""

    name: str
    # its entry in `bench --suite`'s help
    help: str
    points: Callable[[Plan], list[Point]]
    # the record suites its points write (Point.suite); empty: its own name
    records: tuple[str, ...] = ()
    # how the runner times a point: "frame" (runner.measure), "dynamic"
    # (runner.measure_dynamic: the spheres move), "workers" (bench.multi.measure)
    measure: str = "frame"
    # its brute-force points (the meshes suite: every point) carry cap_s, and one predicted
    # past it is recorded as skipped (the meshes suite's also where it would not fit)
    capped: bool = False
    # why it runs on one machine only (not across a cluster with --scheduler); empty: it runs anywhere
    one_machine: str = ""
    # the report gives it a section of its own, apart from the thesis's claims
    section: bool = False

    @property
    def writes(self) -> tuple[str, ...]:
        return self.records or (self.name,)


def _thesis(plan: Plan) -> list[Point]:
    out = []
    sizes = THESIS_SIZES[:1] if plan.quick else THESIS_SIZES
    counts = (100, 500, 1000) if plan.quick else THESIS_COUNTS
    for way, device in plan.runs:
        for i, (w, h) in enumerate(sizes):
            test = (1 if device in GPUS else 4) + i
            out += [Point("thesis", device, w, h, n, dict(way), test=test) for n in counts]
    out = _with_repeats(out)
    first, last, step = (10, 200, 10) if plan.quick else RAMP
    ramp = tuple(range(first, last + 1, step))
    w, h = (320, 240) if plan.quick else RAMP_SIZE
    # the ramp changes the sphere count every frame: brute force only (a BVH would be rebuilt each frame)
    out += [
        Point("test7", device, w, h, ramp[-1], dict(way), test=7, ramp=ramp)
        for way, device in plan.runs
        if way["accel"] == "none"
    ]
    return out


def _with_repeats(points: list[Point]) -> list[Point]:
    """The thesis points with each device's headline points timed again: the first repeat in
    the middle of that device's points (after the headline's own), each later one after its
    last point."""
    out = list(points)
    for device in dict.fromkeys(p.device for p in points):
        mine = [i for i, p in enumerate(out) if p.device == device]
        again = [
            p
            for p in out
            if p.device == device and headline.counts_point(p.suite, device, (p.width, p.height), p.spheres, p.options)
        ]
        if not again:
            continue
        middle = max(mine[len(mine) // 2], max(out.index(p) for p in again) + 1)
        out[mine[-1] + 1 : mine[-1] + 1] = [replace(p, repeat=k) for k in range(2, HEADLINE_REPEATS + 1) for p in again]
        out[middle:middle] = [replace(p, repeat=1) for p in again]
    return out


def _constant_vs_runtime(plan: Plan) -> list[Point]:
    out = []
    counts = (100, 500) if plan.quick else CONSTANT_COUNTS
    w, h = (640, 480) if plan.quick else THESIS_SIZES[-1]
    for device in (d for d in plan.devices if d != "wgpu"):  # wgpu has no compile-time count (yet)
        for n in counts:
            for mode in ("constant", "runtime"):
                # the simple kernel: the only one with a compile-time count
                options = {"count": mode, "kernel": "simple", "accel": "none"}
                out.append(Point("constant-vs-runtime", device, w, h, n, options))
    return out


def _tuning(plan: Plan) -> list[Point]:
    out = []
    w, h = (640, 480) if plan.quick else TUNING_SIZE
    n = 300 if plan.quick else TUNING_SPHERES
    for way, device in plan.runs:
        if device == "cpu":
            settings = thread_settings(plan.cores, h)
            if plan.quick:
                settings = [s for s in settings if s[0] in ("1 thread", "all cores", "2x cores")]
            out += [Point("tuning", "cpu", w, h, n, {"threads": t, "label": label, **way}) for label, t in settings]
            continue
        blocks = ((8, 8), (16, 16), (32, 32), (32, 8)) if plan.quick else BLOCKS
        if device == "wgpu":  # the adapter's limit; a driver spills what does not fit in registers
            blocks = tuple(b for b in blocks if b[0] * b[1] <= plan.max_invocations)
            out += [
                Point("tuning", device, w, h, n, {"workgroup": list(b), "label": f"{b[0]}x{b[1]}", **way})
                for b in blocks
            ]
            continue
        if way.get("kernel", "bvh") in ("fast", "bvh"):  # larger blocks cannot launch (options.FAST_MAX_THREADS)
            blocks = tuple(b for b in blocks if b[0] * b[1] <= FAST_MAX_THREADS)
        out += [Point("tuning", device, w, h, n, {"block": list(b), "label": f"{b[0]}x{b[1]}", **way}) for b in blocks]
    return out


def _scaling(plan: Plan) -> list[Point]:
    out = []
    counts = QUICK_SCALING_COUNTS if plan.quick else SCALING_COUNTS
    w, h = QUICK_SCALING_SIZE if plan.quick else SCALING_SIZE
    cap = QUICK_SCALING_CAP_S if plan.quick else SCALING_CAP_S
    for way, device in plan.runs:
        opts = {**way, "cap_s": cap} if way["accel"] == "none" else dict(way)
        out += [Point("scaling", device, w, h, n, dict(opts)) for n in counts]
        if not plan.quick:
            (ew, eh), en = SCALING_EXTRA
            out.append(Point("scaling", device, ew, eh, en, dict(opts)))
        if way["accel"] == "bvh":
            layout_counts = QUICK_SCALING_LAYOUT_COUNTS if plan.quick else SCALING_LAYOUT_COUNTS
            out += [
                Point("scaling", device, w, h, n, {**opts, "layout": layout})
                for layout in SCALING_LAYOUTS
                for n in layout_counts
            ]
    return out


def _secondary(plan: Plan) -> list[Point]:
    # Whitted's brute force is the simple kernel's loop, whatever kernels were
    # asked for; its thesis-shading twin uses the same loop, so that the two
    # differ only in the rays they cast
    ways = [{"accel": "bvh"}] if "bvh" in plan.accels else []
    ways += [{"kernel": "simple", "accel": "none"}] if "none" in plan.accels else []
    sizes = QUICK_SECONDARY_SIZES if plan.quick else SECONDARY_SIZES
    counts = QUICK_SECONDARY_COUNTS if plan.quick else SECONDARY_COUNTS
    cap = QUICK_SECONDARY_CAP_S if plan.quick else SECONDARY_CAP_S
    out = []
    for way, device in _runs(ways, plan.devices, plan.wgpu, plan.builds):
        capped = {"cap_s": cap} if way["accel"] == "none" else {}
        for n in counts:
            for w, h in sizes:
                out += [Point("secondary", device, w, h, n, {**way, **s, **capped}) for s in secondary_shadings()]
    return out


def _multi_gpu(plan: Plan) -> list[Point]:
    out = []
    for device in (d for d in plan.devices if d in MULTI_GPU):  # wgpu has no cluster workers
        (fw, fh), ((sw, sh), frames), n = QUICK_MULTI_GPU if plan.quick else MULTI_GPU[device]
        # the BVH: the suite asks how workers scale, not how brute force does
        own = {"accel": "bvh", **({"threads": 1} if device == "cpu" else {})}
        for workers in worker_counts(device, plan.cores, plan.gpus):
            out.append(Point("multi-gpu", device, fw, fh, n, {"workers": workers, "job": "frame", **own}))
            sequence = {"workers": workers, "job": "sequence", "frames": frames, **own}
            out.append(Point("multi-gpu", device, sw, sh, n, sequence))
    return out


def _scenes(plan: Plan) -> list[Point]:
    """The SPD's scenes at their size factors (bench/scenes.py), each with Haines's count of its
    primitives and the triangles raybench traces for its polygons and cones; then the example
    molecule and its copies, each with its atom count."""
    sizes = scenes.QUICK_SCENES_SIZES if plan.quick else scenes.SCENES_SIZES
    w, h = scenes.QUICK_SCENES_SIZE if plan.quick else scenes.SCENES_SIZE
    out = []
    for way, device in _runs([{"accel": "bvh"}], plan.devices, plan.wgpu, plan.builds):
        for kind, factors in sizes.items():
            for size in factors:
                name = f"{kind} {size}"
                options = {**way, "scene": name, "shading": "whitted", "depth": scenes.SCENES_DEPTH,
                           "shadow_samples": 1, "primitives": scenes.primitives(name),
                           "triangles": scenes.triangles(name)}  # fmt: skip
                out.append(Point("scenes", device, w, h, scenes.nff(name).counts()["spheres"], options))
        copies = scenes.QUICK_MOLECULE_COPIES if plan.quick else scenes.MOLECULE_COPIES
        for k in copies:
            atoms = scenes.molecule_atoms(scenes.MOLECULE) * k
            options = {**way, "molecule": scenes.MOLECULE, "copies": k, "atoms": atoms, "style": scenes.MOLECULE_STYLE,
                       "shading": "whitted", "depth": scenes.SCENES_DEPTH, "shadow_samples": 1}  # fmt: skip
            out.append(Point("scenes", device, w, h, atoms, options))
    return out


def _meshes(plan: Plan) -> list[Point]:
    """Triangles (bench/meshes.py): each mesh at its counts, the thesis's shading then Whitted's,
    through the BVH, on every device asked for; a point past the cap or the memory is skipped."""
    w, h = meshes.QUICK_SIZE if plan.quick else meshes.SIZE
    cap = meshes.QUICK_CAP_S if plan.quick else meshes.CAP_S
    out = []
    for way, device in _runs([{"accel": "bvh"}], plan.devices, plan.wgpu, plan.builds):
        for kind in meshes.KINDS:
            for n in meshes.counts(kind, plan.quick):
                mesh = {"mesh": kind, "triangles": n}
                out += [Point("meshes", device, w, h, 0, {**way, **mesh, **s, "cap_s": cap}) for s in meshes.shadings()]
    return out


def _dynamic(plan: Plan) -> list[Point]:
    counts = QUICK_DYNAMIC_COUNTS if plan.quick else DYNAMIC_COUNTS
    w, h = QUICK_DYNAMIC_SIZE if plan.quick else DYNAMIC_SIZE
    out = []
    for way, device in _runs([{"accel": "bvh"}], plan.devices, plan.wgpu, plan.builds or BUILDS):
        out += [Point("dynamic", device, w, h, n, {**way, "motion": "orbits"}) for n in counts]
    return out


THESIS = Suite("thesis", "thesis", _thesis, records=("thesis", "test7"))
CONSTANT_VS_RUNTIME = Suite("constant-vs-runtime", "constant-vs-runtime", _constant_vs_runtime)
TUNING = Suite("tuning", "tuning", _tuning)
SCALING = Suite("scaling", "scaling", _scaling, capped=True, section=True)
SECONDARY = Suite(
    "secondary", "secondary (Whitted frames: shadows, mirrors, glass)", _secondary, capped=True, section=True
)
MULTI_GPU_SUITE = Suite(
    "multi-gpu",
    "multi-gpu (1 to N workers of raybench.cluster on this machine)",
    _multi_gpu,
    measure="workers",
    one_machine="starts its own workers",
    section=True,
)
DYNAMIC = Suite(
    "dynamic",
    "dynamic (spheres that move every frame: the tree's update and the frame)",
    _dynamic,
    measure="dynamic",
    section=True,
)
SCENES = Suite(
    "scenes",
    "scenes (the SPD's scenes at their size factors, Whitted as each defines it; a molecule, 5 thousand to 5 "
    "million atoms)",
    _scenes,
    section=True,
)
MESHES = Suite(
    "meshes",
    "meshes (triangles: an icosphere and random triangles, 10 thousand to 10 million, primary and Whitted rays)",
    _meshes,
    capped=True,
    section=True,
)

# Every suite, in run order: `bench --suite`'s choices and `--suite all`, the
# runner's dispatch, the record suites the schema takes and the report's sections.
REGISTRY = (THESIS, CONSTANT_VS_RUNTIME, TUNING, SCALING, SECONDARY, MULTI_GPU_SUITE, DYNAMIC, SCENES, MESHES)
_BY_NAME = {s.name: s for s in REGISTRY}
_BY_RECORD = {r: s for s in REGISTRY for r in s.writes}
SUITES = tuple(_BY_NAME)
# What a results record's suite may be (results_schema.SUITES adds none): the points' suites.
RECORDS = tuple(_BY_RECORD)
# The record suites whose points may be recorded as skipped past a frame-time cap.
CAPPED = tuple(r for s in REGISTRY if s.capped for r in s.writes)


def suite(name: str) -> Suite:
    """The suite of that name (bench --suite's), or an error naming the choices."""
    if name not in _BY_NAME:
        raise RaybenchError(f"suite: unknown suite {name!r}; choose from {', '.join(SUITES)}")
    return _BY_NAME[name]


def owner(record_suite: str) -> Suite:
    """The suite whose points write records of that suite (test7's: the thesis)."""
    return _BY_RECORD[record_suite]


def points(
    suites,
    devices,
    quick: bool = False,
    cores: int | None = None,
    kernels=("fast",),
    accels=("none",),
    wgpu: dict | None = None,
    max_invocations: int = 1024,
    gpus: int = 0,
    builds=(),
) -> list[Point]:
    """Every point of the chosen suites on the chosen devices (the thesis,
    tuning and scaling suites once per kernel of brute force, and once more
    with the BVH if accels holds "bvh"), in run order: REGISTRY's, whatever
    the order asked for. wgpu: that device's options ({"adapter": name});
    max_invocations: its adapter's workgroup limit, which bounds the tuning
    suite's shapes; gpus: the machine's GPU count, the multi-gpu suite's
    largest count of cuda workers. builds: where cuda's BVH points build
    their trees (_runs)."""
    chosen = {suite(name).name for name in suites}
    for accel in accels:
        if accel not in ACCELS:
            raise RaybenchError(f"accel: unknown accel {accel!r}; choose from {', '.join(ACCELS)}")
    plan = Plan(
        devices=tuple(devices),
        quick=quick,
        cores=cores or usable_cores(),
        kernels=tuple(kernels),
        accels=tuple(accels),
        wgpu=wgpu or {},
        max_invocations=max_invocations,
        gpus=gpus,
        builds=tuple(builds),
        runs=_runs(variants(kernels, accels), devices, wgpu or {}, builds),
    )
    return [p for s in REGISTRY if s.name in chosen for p in s.points(plan)]
