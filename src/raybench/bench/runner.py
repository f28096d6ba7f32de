"""Time the points of a suite and append one record per point as it finishes."""

from __future__ import annotations

import datetime
import json
import re
import sys
import time
import uuid

from .. import animate, backends
from ..camera import Camera
from ..errors import RaybenchError
from ..layout import KINDS
from ..machine import describe, git_commit
from ..render import Renderer
from ..scene import random_spheres
from . import meshes, multi, pictures, suites
from .results import ResultsWriter
from .stats import kept_samples, summarize
from .suites import DYNAMIC_DT, Point

MIN_FRAMES = 3
WARMUP_S = 1.0


def tracer_options(point: Point) -> dict:
    """The backend options of a point (its label and count mode are bookkeeping;
    its shading, which needs the scene, measure() adds)."""
    opts = {}
    if "threads" in point.options:
        opts["threads"] = point.options["threads"]
    if "block" in point.options:
        opts["block"] = tuple(point.options["block"])
    if "workgroup" in point.options:
        opts["workgroup"] = tuple(point.options["workgroup"])
    if "adapter" in point.options:
        opts["adapter"] = point.options["adapter"]
    if "kernel" in point.options:
        opts["kernel"] = point.options["kernel"]
    if "accel" in point.options:
        opts["accel"] = point.options["accel"]
    if "build" in point.options:  # cuda's and wgpu's: where the tree is built
        opts["build"] = point.options["build"]
    if point.options.get("count") == "constant":
        opts["constant_count"] = True
    return opts


def whitted(point: Point) -> bool:
    """Whether a point traces Whitted frames: the secondary suite's, of the
    materials scene, and the scenes suite's, of their own; every other point
    is the thesis's shading."""
    return point.options.get("shading") == "whitted"


class Scenes:
    """The benchmark's scenes: random_spheres(n, seed), made once each, the same
    on every device; with materials (the same spheres, lit) for Whitted points;
    in another layout (the scaling suite's denser scenes) where a point says so."""

    def __init__(self, seed: int):
        self.seed = seed
        self._cache = {}

    def get(self, n: int, materials: bool = False, layout: str = "even"):
        key = (n, materials, layout)
        if key not in self._cache:
            self._cache[key] = random_spheres(n, self.seed, materials=materials, layout=layout)
        return self._cache[key]


def _frame(tracer, basis, count=None) -> tuple[float, float | None]:
    start = time.perf_counter()
    kernel_ms = tracer.timed_trace(basis, count)
    return (time.perf_counter() - start) * 1e3, kernel_ms


def measure_dynamic(point: Point, scenes: Scenes, duration: float) -> dict:
    """Time a point of the dynamic suite: each frame moves the spheres
    (animate.Orbits at the next DYNAMIC_DT, computed before the clock
    starts, as a program would have its spheres' positions), then updates
    the tree (Tracer.update: refit or build, uploads included) and traces
    the frame; frame_ms is both, update_ms the update alone. A first moved
    frame and a warm-up are left out, as in measure()."""
    scene = scenes.get(point.spheres)
    basis = Camera().basis(point.width, point.height)
    orbits = animate.Orbits(scene.spheres, scenes.seed)
    # made as a program makes it (raybench.Renderer); its tracer is timed
    renderer = Renderer(scene, point.width, point.height, point.device, **tracer_options(point))
    tracer = renderer.tracer
    clock = iter(range(1, 1 << 62))

    def frame() -> tuple[float, float, float | None, str | None]:
        spheres = orbits.at(next(clock) * DYNAMIC_DT)
        start = time.perf_counter()
        kind = tracer.update(spheres)
        update_ms = (time.perf_counter() - start) * 1e3
        kernel_ms = tracer.timed_trace(basis)
        return (time.perf_counter() - start) * 1e3, update_ms, kernel_ms, kind

    try:
        build_s = tracer.build_s
        described, compile_s = tracer.describe(), tracer.compile()
        first_ms = frame()[0]
        end_warmup = time.perf_counter() + min(WARMUP_S, duration / 2)
        while time.perf_counter() < end_warmup:
            frame()
        frames = []
        end = time.perf_counter() + duration
        while time.perf_counter() < end or len(frames) < MIN_FRAMES:
            frames.append(frame())
        walk = tracer.walk
    finally:
        renderer.close()
    frame_ms, update_ms = [f[0] for f in frames], [f[1] for f in frames]
    kernel_ms = [f[2] for f in frames if f[2] is not None]
    kinds = [f[3] for f in frames]
    record = {
        **_identity(point),
        "frames": len(frames),
        "frame_ms": summarize(frame_ms),
        "kernel_ms": summarize(kernel_ms) if kernel_ms else None,
        "samples_ms": kept_samples(frame_ms),
        "update_ms": summarize(update_ms),
        "updates": {kind: kinds.count(kind) for kind in ("refit", "build") if kind in kinds},
        "update_share": sum(update_ms) / sum(frame_ms),
        "frames_per_s": 1e3 / summarize(frame_ms)["median"],
        "first_frame_s": first_ms / 1e3,
        "compile_s": compile_s,
        "build_s": build_s,
        "rays_per_s": point.width * point.height / (summarize(frame_ms)["median"] / 1e3),
        "tests_per_s": None,
    }
    if described is not None:
        record["adapter"] = described
    if walk is not None:
        record["walk"] = walk
    return record


def measure(point: Point, scenes: Scenes, duration: float) -> dict:
    """Time one point: compile, one first frame, warm-up, then frames for
    `duration` seconds (at least MIN_FRAMES). The ramp (test 7) instead traces
    one frame per sphere count and keeps all but the first. A Whitted point
    also records the rays its frames cast, by kind, as the kernel counted
    them (every frame of a point casts the same: scene, camera and the area
    light's sample pattern are fixed)."""
    shaded = whitted(point)
    if "scene" in point.options:  # the scenes suite's: a scene of its own, seen from its own view
        from . import scenes as real

        scene = real.scene(point.options["scene"])
        basis = (scene.camera or Camera()).basis(point.width, point.height)
    elif "molecule" in point.options:  # the scenes suite's molecules: copies of one, its own camera and light
        from . import scenes as real

        scene = real.molecule_scene(point.options["molecule"], point.options["copies"])
        basis = scene.camera.basis(point.width, point.height)
    elif "mesh" in point.options:  # the meshes suite's: triangles, where they fit
        why = meshes.too_large(point.options["triangles"])
        if why is not None:
            return unfit(point, why)
        scene = meshes.mesh_scene(point.options["mesh"], point.options["triangles"], scenes.seed)
        basis = scene.camera.basis(point.width, point.height)
    else:
        scene = scenes.get(point.spheres, materials=shaded, layout=point.options.get("layout", "even"))
        basis = Camera().basis(point.width, point.height)
    # made as a program makes it (raybench.Renderer); its tracer is timed, the
    # frame's kernel and readback without Renderer.render's copies
    try:
        renderer = Renderer(
            scene, point.width, point.height, point.device, "whitted" if shaded else "thesis",
            point.options.get("depth") if shaded else None, point.options.get("shadow_samples") if shaded else None,
            **tracer_options(point),
        )  # fmt: skip
    except RaybenchError as exc:
        # a mesh or a molecule of millions of atoms the device cannot hold (its memory, a
        # storage-buffer limit) is refused in one line before anything is allocated: the
        # suite's point skipped with it, the run going on
        if "mesh" not in point.options and "molecule" not in point.options:
            raise
        return unfit(point, str(exc))
    tracer = renderer.tracer
    try:
        build_s = tracer.build_s
        walk = tracer.walk  # cuda's BVH walk: "ray" or "packet", chosen by the tree
        # wgpu: which adapter ran it (a GPU, or a CPU driver such as lavapipe), and how it was timed
        described = tracer.describe()
        compile_s = tracer.compile()
        if point.ramp:
            first_ms, _ = _frame(tracer, basis, point.ramp[0])
            frames = [_frame(tracer, basis, n) for n in point.ramp[1:]]
        else:
            first_ms, _ = _frame(tracer, basis)
            end_warmup = time.perf_counter() + min(WARMUP_S, duration / 2)
            while time.perf_counter() < end_warmup:
                _frame(tracer, basis)
            frames = []
            end = time.perf_counter() + duration
            while time.perf_counter() < end or len(frames) < MIN_FRAMES:
                frames.append(_frame(tracer, basis))
        counts = None if tracer.ray_counts is None else [int(c) for c in tracer.ray_counts]
        # a real scene's picture rides in its record: the report shows what was traced
        picture = pictures.thumbnail(tracer.image) if point.suite == "scenes" else None
    finally:
        renderer.close()
    frame_ms = [f for f, _ in frames]
    kernel_ms = [k for _, k in frames if k is not None]
    record = {
        **_identity(point),
        "frames": len(frames),
        "frame_ms": summarize(frame_ms),
        "kernel_ms": summarize(kernel_ms) if kernel_ms else None,
        "first_frame_s": first_ms / 1e3,
        "compile_s": compile_s,
        "build_s": build_s,
    }
    bvh = point.options.get("accel") == "bvh"
    # what only some records have: the adapter, the walk a tree chose, a real scene's picture
    record.update({k: v for k, v in (("adapter", described), ("walk", walk), ("picture", picture)) if v is not None})
    if not point.ramp:  # a ramp's frames are its series, one per count
        record["samples_ms"] = kept_samples(frame_ms)
    if point.ramp:
        record["series"] = {"spheres": list(point.ramp[1:]), "frame_ms": frame_ms, "kernel_ms": kernel_ms or None}
        rays = point.width * point.height
        record["rays_per_s"] = rays * len(frames) / (sum(frame_ms) / 1e3)
        record["tests_per_s"] = rays * sum(point.ramp[1:]) / (sum(frame_ms) / 1e3)
    elif shaded:
        # every kind of ray counted; no tests/s: shadow rays stop at their first blocker
        total = sum(counts)
        record["rays"] = dict(zip(KINDS, counts))
        record["rays_per_frame"] = total
        record["rays_per_s"] = total / (record["frame_ms"]["median"] / 1e3)
        record["kernel_rays_per_s"] = total / (record["kernel_ms"]["median"] / 1e3) if kernel_ms else None
        record["tests_per_s"] = None
    else:
        median_s = record["frame_ms"]["median"] / 1e3
        record["rays_per_s"] = point.width * point.height / median_s
        # the BVH tests only the spheres its walk reaches: rays x spheres would be no count of its work
        record["tests_per_s"] = None if bvh else point.width * point.height * point.spheres / median_s
    return record


def _series(point: Point) -> tuple:
    """The points a capped point predicts its frame time from: the same
    suite, device and way of tracing, any size and count (of spheres, or a mesh's triangles)."""
    opts = {k: v for k, v in point.options.items() if k not in ("cap_s", "triangles")}
    return point.suite, point.device, json.dumps(opts, sort_keys=True)


def predicted_ms(point: Point, last: tuple | None) -> float | None:
    """Frame time predicted for point from (pixels, spheres, median ms) of the
    last point of its series: linear in spheres and in pixels."""
    if last is None:
        return None
    pixels, spheres, ms = last
    return ms * (point.width * point.height / pixels) * (max(point.spheres, 1) / max(spheres, 1))


def _count(point: Point) -> int:
    """What a point's frame time is predicted to grow with: its triangles, else its spheres."""
    return point.options.get("triangles", point.spheres)


def _predicted(point: Point, series: list[tuple]) -> float | None:
    """A capped point's frame predicted from its series' points measured before it: a mesh's
    by the growth they showed (meshes.predicted_ms), any other's linear from the last."""
    if "triangles" in point.options:
        return meshes.predicted_ms(point.width * point.height, _count(point), series)
    return predicted_ms(point, series[-1] if series else None)


def _identity(point: Point) -> dict:
    """What every record says of its point, measured or skipped."""
    return {
        "suite": point.suite,
        "test": point.test,
        "device": point.device,
        "width": point.width,
        "height": point.height,
        "spheres": point.spheres,
        "options": point.options,
        **({"repeat": point.repeat} if point.repeat else {}),
    }


def skipped(point: Point, predicted: float, cap_s: float) -> dict:
    """The record of a point not measured: its frame would take too long."""
    return {
        **_identity(point),
        "skipped": f"predicted {predicted / 1e3:.3g} s a frame, over the {cap_s:g} s cap",
        "predicted_ms": predicted,
    }


def unfit(point: Point, why: str) -> dict:
    """The record of a point not measured: it would not fit in memory (the meshes suite's)."""
    text = " ".join(f"does not fit: {why}".split())
    return {**_identity(point), "skipped": text if len(text) <= 300 else text[:297] + "...", "predicted_ms": None}


def machine_label(machine: dict) -> str:
    """A short name for the machine, for folders and report columns."""
    if machine["gpus"]:
        name = machine["gpus"][0]["name"]
    else:
        name = f"{machine['cpu']['model']} {machine['cpu']['physical_cores']}c"
    slug = re.sub(r"[^a-z0-9]+", "-", name.lower().replace("(r)", "").replace("(tm)", "")).strip("-")
    return slug or "machine"


def run_info(machine: dict, label: str, settings: dict, argv: list[str] | None = None) -> dict:
    return {
        "id": uuid.uuid4().hex[:12],
        "date": datetime.datetime.now(datetime.UTC).isoformat(timespec="seconds"),
        "git_commit": git_commit(),
        "label": label,
        "argv": sys.argv[1:] if argv is None else list(argv),
        "settings": settings,
        "machine": machine,
    }


def plan(settings: dict, label: str | None = None, argv: list[str] | None = None) -> tuple[list[Point], dict]:
    """This machine's points of the bench's settings, and the run info its
    records carry: the same on the command line's machine and inside a
    cluster's worker (raybench.bench.machines.bench), each with its own machine's
    description. settings["devices"] empty: every device present here; each
    named is checked here. Its other keys are the CLI's: suites, kernels,
    accels, builds, duration_s, quick, seed, adapter (any more are kept in
    the run info as they are)."""
    devices = tuple(settings["devices"]) or tuple(backends.present())
    adapter = settings.get("adapter")
    for d in devices:
        if d not in backends.DEVICES:
            raise RaybenchError(f"--device: unknown device {d!r}; choose from {', '.join(backends.DEVICES)}")
        backends.resolve(d, adapter)
    if adapter is not None and "wgpu" not in devices:
        raise RaybenchError("--adapter applies to --device wgpu only")
    builds = tuple(settings["builds"])
    if builds and not {"cuda", "wgpu"} & set(devices):
        raise RaybenchError("--build applies to --device cuda and wgpu only")
    wgpu_options, max_invocations = {}, 1024
    if "wgpu" in devices:
        chosen_adapter = backends.module("wgpu").choose(adapter)
        wgpu_options = {"adapter": adapter} if adapter is not None else {}
        max_invocations = chosen_adapter.adapter.limits["max-compute-invocations-per-workgroup"]
    machine = describe()
    points = suites.points(
        tuple(settings["suites"]),
        devices,
        quick=settings["quick"],
        kernels=tuple(settings["kernels"]),
        accels=tuple(settings["accels"]),
        wgpu=wgpu_options,
        max_invocations=max_invocations,
        gpus=len(machine["gpus"]),
        builds=builds,
    )
    info = run_info(machine, label or machine_label(machine), {**settings, "devices": list(devices)}, argv)
    return points, info


def _timed(point: Point, scenes: Scenes, duration: float, clusters: multi.Clusters) -> dict:
    """A point's record, timed the way its suite declares (suites.Suite.measure)."""
    how = suites.owner(point.suite).measure
    if how == "workers":  # the multi-gpu suite's: a cluster kept open from one point to the next
        return multi.measure(point, scenes, duration, clusters)
    clusters.close()
    # looked up at each call, not bound once: a test may stand in for either
    timed = {"frame": measure, "dynamic": measure_dynamic}[how]
    return timed(point, scenes, duration)


class Records:
    """A writer that keeps the records in a list: a cluster worker's run
    (raybench.bench.machines.bench), sent back whole when it ends."""

    def __init__(self):
        self.records: list[dict] = []

    def write(self, record: dict) -> None:
        self.records.append(record)

    @property
    def count(self) -> int:
        return len(self.records)


def run(
    points: list[Point],
    writer: ResultsWriter | Records,
    run: dict,
    duration: float,
    seed: int,
    progress: bool = True,
    lines=None,
) -> int:
    """Measure every point in order, writing each record as soon as it is done.
    Returns how many points were written; Ctrl-C stops between frames and
    propagates, with every finished point already on disk. progress: rich's
    bar (a terminal); lines: a function that prints a line, for plain
    progress lines instead (a file, a pipe or a CI log: bench.progress)."""
    from rich.progress import BarColumn, Progress, TextColumn, TimeElapsedColumn, TimeRemainingColumn

    from .progress import Lines

    scenes = Scenes(seed)
    last: dict[tuple, list] = {}  # each series' (pixels, count, median ms), in order
    weights = [duration + WARMUP_S + (duration if p.ramp else 0) for p in points]
    columns = [
        TextColumn("{task.description}"),
        BarColumn(),
        TextColumn("{task.fields[done]}/{task.fields[count]} points"),
        TimeElapsedColumn(),
        TextColumn("left"),
        TimeRemainingColumn(),
    ]
    clusters = multi.Clusters()  # the multi-gpu suite's, one open at a time
    plain = Lines(lines, points, weights) if lines is not None else None
    try:
        with Progress(*columns, disable=not progress, transient=False) as bar:
            _measure_all(points, weights, writer, run, duration, scenes, last, clusters, bar, plain)
    finally:
        if plain is not None:
            plain.close()
    clusters.close()
    return writer.count


def _measure_all(points, weights, writer, run, duration, scenes, last, clusters, bar, plain) -> None:
    """run()'s loop: each point timed (or recorded as skipped past its cap) and written."""
    task = bar.add_task("", total=sum(weights), done=0, count=len(points))
    for i, (point, weight) in enumerate(zip(points, weights)):
        bar.update(task, description=point.describe())
        if plain is not None:
            plain.point(i, point)
        cap_s = point.options.get("cap_s")
        series = last.setdefault(_series(point), [])
        guess = _predicted(point, series) if cap_s else None
        if guess is not None and guess > cap_s * 1e3:
            writer.write({**skipped(point, guess, cap_s), "run": run})
        else:
            try:
                record = _timed(point, scenes, duration, clusters)
            except BaseException:
                clusters.close()
                raise
            if "skipped" not in record:  # (a mesh that did not fit: nothing to predict from)
                series.append((point.width * point.height, _count(point), record["frame_ms"]["median"]))
            writer.write({**record, "run": run})
        bar.update(task, advance=weight, done=i + 1)
        if plain is not None:
            plain.done(i)
