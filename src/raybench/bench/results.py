"""Benchmark results as JSON Lines: one record per measured point, appended and
flushed to disk as soon as the point finishes, so an interrupted run keeps
every point it finished.

A record (format "raybench-results", version 1):

    suite        "thesis" | "test7" | "constant-vs-runtime" | "tuning" | "scaling" | "secondary" |
                 "multi-gpu" | "dynamic" | "scenes" | "meshes" | "parts" (below)
    test         the thesis's test number (1-3 GPU, 4-6 CPU by resolution; 7 the ramp), else null
    device       "cpu" | "cuda"
    width, height, spheres
    options      the device options used: {"threads": N} (cpu) or {"block": [x, y]} (cuda),
                 and for constant-vs-runtime {"count": "constant" | "runtime"};
                 tuning points carry "label", e.g. "2x cores" or "one per row";
                 "accel": "bvh" | "none" (absent in older records: none), "kernel"
                 for brute force; scaling's and secondary's brute-force points carry "cap_s";
                 scaling's points of a denser scene carry "layout" (random_spheres's:
                 "dense", "clusters", "deep"; absent: "even"), and the cpu's, where its
                 tree was chosen, "tree_width" (2 or 4: the cpu Tracer's tree_width);
                 benchmarks/gpu_build.py's BVH points also "quality" (of a tree built on
                 the GPU) and "walk" ("ray" or "packet"); its dynamic points "policy";
                 secondary's points carry "shading": "thesis" (primary rays, the baseline) or
                 "whitted" with "depth" and "shadow_samples" (the materials scene,
                 random_spheres(n, seed, materials=True)); multi-gpu's carry "workers" (of
                 raybench.cluster), "job": "frame" (one frame in tiles) or "sequence" (an
                 orbit of "frames" frames), and on the cpu "threads" (a worker's);
                 benchmarks/multi_gpu.py's also "delivery": "shared" or "sent" (a frame's
                 tiles), "counts" or "png" (an orbit's frames);
                 "build": "host" | "gpu" where
                 cuda's tree is built (cuda's BVH points, when asked for; always in dynamic);
                 dynamic's points carry "motion": "orbits" (raybench.animate.Orbits);
                 scenes' points "scene" (an SPD scene and its size factor, "balls 4"),
                 "primitives" (Haines's count: spheres, polygons, patches, cones) and
                 "triangles" (what raybench traces for its polygons and cones; earlier
                 records, from before triangles were drawn, have "unrendered" instead);
                 its molecules' points "molecule" (an example's name, "1tii"), "copies"
                 (of it side by side, 1 to 100,000), "atoms" (theirs; spheres the same)
                 and "style" ("spacefill" or "ball-and-stick");
                 meshes' points "mesh" ("icosphere" or "random": bench/meshes.py) and
                 "triangles" (its count; spheres is 0), "shading" as secondary's, "cap_s"
    frames       how many timed frames
    frame_ms     {mean, median, p5, p95, min, max}: whole frame (kernel, and on the GPU the copy to the host);
                 multi-gpu's: a run of the job's wall time over its frames, on all its workers
    samples_ms   the frames' own times in ms (multi-gpu: its runs'), at most 1000 evenly strided
                 (bench.stats.kept_samples): raybench compare's bootstrap; absent in older records
    frames_per_s multi-gpu and dynamic: frames a second from the median (multi-gpu: the workers' throughput)
    kernel_ms    the same for the kernel alone (CUDA events), or null on the CPU
    rays_per_s, tests_per_s   from the median frame (tests = rays x spheres; null for the BVH);
                 under Whitted shading rays_per_s counts every ray cast, and tests_per_s is null
    rays         Whitted points only: the rays a frame cast by kind, as the kernel counted them,
                 {"primary", "shadow", "reflection", "refraction"}; rays_per_frame their sum;
                 kernel_rays_per_s the same rays over the median kernel time, or null
    update_ms    dynamic only: the same for the tree's update alone (Tracer.update: refit
                 or build, with any upload), a part of each frame_ms; updates: how many
                 frames refitted and rebuilt, {"refit"?: N, "build"?: N}; update_share:
                 the updates' time over the frames' (sums); frames_per_s from the median frame
    picture      scenes only: the last frame traced, at most 320 pixels across, a JPEG as a data: URI
                 (bench.pictures), which the report shows; absent in older records
    build_s      the BVH's build time (seconds, compiled code only), or null for brute force
    first_frame_s   the first frame of the point, never averaged in
    compile_s       compiling the kernel for the point, if it was not yet compiled, else 0
    series       test7 only: {"spheres": [...], "frame_ms": [...], "kernel_ms": [... or null]},
                 one entry per frame after the first
    suite "parts": what a benchmark script times that is no suite's frame (a build, a
                 start-up, a launch, a part of a frame, an encoding), in place of the fields
                 above but suite, device, options and run:
        quantity     what was timed, a name (e.g. "bvh-build", "startup-warm", "launch")
        spheres, width, height   the scene's and the image's, where there are ones
        samples      how many timings time_ms summarises
        time_ms      {median, p5, p95, mean?, min?, max?}: one timing of the quantity
        samples_ms   the timings themselves, as a point's
        values       other figures measured with it, by name (an SAH cost, a depth, bytes),
                     numbers or null
    skipped      instead of frames, frame_ms, ...: why the point was not measured (the
                 scaling and secondary suites' brute force, the meshes suite's points), e.g.
                 "predicted 4.2 s a frame, over the 1 s cap", with predicted_ms; a mesh that
                 would not fit: "does not fit: ..." (the refusal's line), predicted_ms null
    Every field's rule is in the schema (bench.results_schema), also published as JSON Schema
    (schema(): `raybench schema`, docs/results-schema.json).
    run          {"id", "date", "git_commit", "label", "argv", "settings", "machine": raybench.machine.describe()}
"""

from __future__ import annotations

import json
import math
import os
import re
import warnings
from pathlib import Path

import numpy as np

from ..errors import RaybenchError, shown
from ..files import Appended, check_nesting, check_writable, parse, read_text, signals_held
from .results_schema import MAX_NUMBER as MAX_NUMBER  # cli.bench imports it from here
from .results_schema import (
    MEASURED,
    PART,
    PLAIN,
    POINT,
    RUN,
    SERIES,
    SKIPPED,
    _Bad,
    _name,
    _object_of,
    _plain,
    forget_times,
    times_array,
)
from .results_schema import NAME as NAME  # benchmarks/_harness.py reads it from here
from .suites import CAPPED

FORMAT = "raybench-results"
VERSION = 1


class ResultsWriter:
    """Appends records to a .jsonl file, each on disk before the next point
    starts. The file is created with the first record: a run stopped before
    its first point leaves nothing behind."""

    def __init__(self, path):
        self.path = Path(path)
        if os.path.isdir(self.path):
            raise RaybenchError(f"{self.path}: cannot write results: it is a folder")
        # Refuse an unwritable place now, not after the first point's minutes.
        existing = self.path.parent
        while not os.path.lexists(existing) and existing != existing.parent:
            existing = existing.parent
        if not os.path.isdir(existing):
            raise RaybenchError(f"{self.path}: cannot write results: {existing} is not a folder")
        check_writable(existing / self.path.name, "results")
        self._existing = existing  # the folders below it are made with the first record
        self._file = None
        self.count = 0

    def write(self, record: dict) -> None:
        line = json.dumps({"format": FORMAT, "version": VERSION, **record}, separators=(",", ":"))
        if self._file is None:
            try:
                self.path.parent.mkdir(parents=True, exist_ok=True)
            except OSError as exc:
                raise RaybenchError(f"{self.path}: cannot write results ({exc.strerror or exc})") from None
            self._file = Appended(self.path, "results")
        # One record a piece, on disk before the next point starts; one that
        # fails part way is cut off, and the first makes the file whole or not
        # at all (files.Appended): a full disk leaves no empty file. Ctrl-C or
        # SIGTERM meanwhile is raised once the record is written and counted.
        with signals_held():
            try:
                self._file.append((line + "\n").encode("utf-8"))
            except RaybenchError:
                if not self.count:  # no file was made: nor are the folders made for it left
                    self._remove_made_folders()
                raise
            except OSError as exc:  # (the first record's failure is write_atomic's one line: nothing was changed)
                raise RaybenchError(
                    f"{self.path}: cannot write results ({exc.strerror or exc}); the {self.count} records before "
                    "this one are kept"
                ) from None
            self.count += 1

    def close(self) -> None:
        if self._file is not None:
            self._file.close()

    def _remove_made_folders(self) -> None:
        folder = self.path.parent
        while folder != self._existing and self._existing in folder.parents:
            try:
                folder.rmdir()  # only where empty
            except OSError:
                return
            folder = folder.parent

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()


def read(path, compact: bool = False) -> list[dict]:
    """All records of one results file, each checked against the schema
    below. A half-written last line is skipped with a warning; a file that is
    not ours, or damaged before its end, is an error naming the line.
    compact: each record's samples_ms as a NumPy array once checked (a
    quarter of the list's memory: compare holds two files of them)."""
    path = Path(path)
    return parse_records(read_text(path, "results file"), path, compact)


def parse_records(text: str, path, compact: bool = False) -> list[dict]:
    """The records of a results file's text (read()), path naming it in messages."""
    check_nesting(text, str(path), lines=True)
    # The last line holding anything: only it may be cut short. Found once, so reading is linear.
    end = len(text.rstrip())
    last = text.count("\n", 0, end) + 1 if end else 0
    records: list[dict] = []
    runs: list[str] = []  # (as JSON text: _same_run)
    for number, line in enumerate(_lines(text), 1):
        if not line.strip():
            continue
        where = f"{path}: line {number}"
        try:
            record = parse(line, where)
        except RaybenchError:
            # Only the writer's own line, cut: any other text is an error wherever it stands.
            if number == last and not text.endswith("\n") and _cut_record(line):
                warnings.warn(f"{path}: line {number} is cut short (an interrupted run?); skipped it", stacklevel=2)
                continue
            raise
        if _SURROGATE.search(line):
            _check_characters(record, where)
        if not isinstance(record, dict) or record.get("format") != FORMAT:
            raise RaybenchError(f"{where} is not a raybench result (format {FORMAT!r} expected)")
        if record.get("version") != VERSION or isinstance(record.get("version"), bool):
            raise RaybenchError(
                f"{where} has results version {shown(record.get('version'))}; this raybench reads version {VERSION}"
            )
        check_record(record, where, runs)
        if compact and "samples_ms" in record:
            record["samples_ms"] = times_array(record["samples_ms"])
        if "repeat" in record:
            _fold(records, record, where)
            continue
        records.append(record)
    if not records:
        raise RaybenchError(f"{path}: holds no results")
    return records


_POINT_KEYS = ("suite", "test", "device", "width", "height", "spheres", "options")


def _fold(records: list[dict], again: dict, where: str) -> None:
    """A repeat of a point (bench times the headline's points again later in the run) goes into
    its point's record, as one of its "repeats": every reader then sees one record a point, and
    the headline's interval reads the passes from there."""
    key = [again.get(k) for k in _POINT_KEYS]
    for record in reversed(records):
        if record["run"] == again["run"] and [record.get(k) for k in _POINT_KEYS] == key and "skipped" not in record:
            kept = {k: again[k] for k in ("frames", "frame_ms", "samples_ms") if k in again}
            record.setdefault("repeats", []).append(kept)
            return
    raise RaybenchError(f"{where}: repeat {again['repeat']} of a point that no line before it holds")


def _lines(text: str):
    """text.split("\n"), a line at a time: a list of every line would double a large file's memory."""
    start = 0
    while start <= len(text):
        end = text.find("\n", start)
        end = len(text) if end < 0 else end
        yield text[start:end]
        start = end + 1


# Every record starts so: as the writer makes it (json.dumps of format, version, then
# the rest), or with json.dumps's default spacing (a script's own writer).
_STARTS = tuple(
    json.dumps({"format": FORMAT, "version": VERSION}, separators=seps)[:-1] + seps[0]
    for seps in ((",", ":"), (", ", ": "))
)
# A JSON escape of a UTF-16 surrogate: paired, it is one character; alone, it is none.
_SURROGATE = re.compile(r"\\u[dD][89a-fA-F][0-9a-fA-F]{2}")


def _cut_record(line: str) -> bool:
    """Whether line can be the start of a record the writer wrote, cut short."""
    return any(line.startswith(start) or start.startswith(line) for start in _STARTS)


def _check_characters(record, where: str) -> None:
    """A lone surrogate (an escape like \\ud800 with no pair) is no character:
    no terminal, file or chart can show it. Refused here, with its place."""
    try:
        json.dumps(record, ensure_ascii=False).encode("utf-8")
    except UnicodeEncodeError as exc:
        lone = exc.object[exc.start : exc.end].encode("unicode_escape", "backslashreplace").decode("ascii")
        raise RaybenchError(f"{where}: holds {lone}, half of a UTF-16 pair: not a character") from None


def _same_run(run, runs: list) -> bool:
    """Whether run is one already checked, compared as written: == would take
    4.0 for 4 and true for 1, and let an unchecked value through."""
    text = json.dumps(run, sort_keys=True)
    return any(text == seen for seen in runs)


def _ordered(times: dict, where: str) -> None:
    """A summary's figures in their order: min <= p5 <= median <= p95 <= max,
    and the mean between min and max (np.percentile's are exactly so)."""
    order = [times[k] for k in ("min", "p5", "median", "p95", "max") if k in times]
    if any(a > b for a, b in zip(order, order[1:])):
        raise _Bad("in order: min <= p5 <= median <= p95 <= max", times).at(where)
    if "mean" in times and not times.get("min", 0) <= times["mean"] <= times.get("max", math.inf) * (1 + 1e-12):
        raise _Bad("between min and max", times["mean"]).at(where + ".mean")


# Kept samples carry 5 significant digits (stats.kept_samples): within this of the summary's.
_KEPT = 1e-4


def _agrees(times: dict, samples: list, count: int | None, where: str) -> None:
    """The kept samples agree with the summary: each between its min and max,
    and, where every sample was kept, their median is the summary's."""
    a = times_array(samples)
    low, high = float(a.min()), float(a.max())
    if low < times.get("min", 0) * (1 - _KEPT) or high > times.get("max", math.inf) * (1 + _KEPT):
        raise _Bad(f"within {where}'s min and max", [low, high]).at("samples_ms")
    if count == len(samples):
        # np.median's value, without its overhead (a record at a time): the middle two of a
        # partition, averaged (the same one twice for an odd count; the times are finite)
        n = len(a)
        middle = np.partition(a, ((n - 1) // 2, n // 2))
        median = float((middle[(n - 1) // 2] + middle[n // 2]) / 2)
        if abs(median - times["median"]) > _KEPT * times["median"]:
            raise _Bad(f"of median {where}.median", median).at("samples_ms")


def check_record(record: dict, where: str, runs: list | None = None) -> None:
    """Every field the report reads, checked for type and range, so a
    hand-edited file fails with one line naming the field, never a traceback
    or a silently wrong report: `where: run.machine.cpu: must be an object`.
    runs: the runs already checked, as JSON text; every record of a run repeats
    its run, which is then compared (at C speed) rather than checked again."""
    forget_times()
    try:
        if record.get("suite") == "parts":
            PART(record)
        else:
            POINT(record)
        if "run" not in record:
            raise _Bad("present", "nothing").at("run")
        if runs is None or not _same_run(record["run"], runs):
            try:
                RUN(record["run"])
            except _Bad as bad:
                raise bad.at("run") from None
            if runs is not None and len(runs) < 16:
                runs.append(json.dumps(record["run"], sort_keys=True))
        if record["suite"] == "parts":
            _ordered(record["time_ms"], "time_ms")
            if record.get("samples_ms"):
                _agrees(record["time_ms"], record["samples_ms"], record.get("samples"), "time_ms")
            return
        if "skipped" in record:
            SKIPPED(record)
            if record["suite"] not in CAPPED:
                raise _Bad(f"absent outside the {' and '.join(CAPPED)} suites", record["skipped"]).at("skipped")
            return
        MEASURED(record)
        for key in ("frame_ms", "kernel_ms", "update_ms"):
            if record.get(key) is not None:
                _ordered(record[key], key)
        if record.get("samples_ms"):
            _agrees(record["frame_ms"], record["samples_ms"], record.get("frames"), "frame_ms")
        if record["suite"] == "test7":
            SERIES(record)
            series = record["series"]
            if len(series["spheres"]) != len(series["frame_ms"]):
                raise _Bad("as long as series.spheres", f"{len(series['frame_ms'])} entries").at("series.frame_ms")
    except _Bad as bad:
        got = "nothing" if bad.what == "present" else shown(bad.value)
        what = "missing" if bad.what == "present" else f"must be {bad.what}, got {got}"
        raise RaybenchError(f"{where}: {bad.path}: {what}") from None


def check_label(label: str, option: str = "--label") -> None:
    """A run's label as the schema takes it, checked before any work (bench, the scripts)."""
    try:
        _name(label)
    except _Bad as bad:
        raise RaybenchError(f"{option}: must be {bad.what}, at most 64 characters, got {shown(label)}") from None


def check_settings(settings: dict) -> None:
    """A run's settings as the schema takes them, checked before any work: a
    run must never write records that its own report then refuses."""
    try:
        _object_of(_plain)(settings)
    except _Bad as bad:
        raise RaybenchError(
            f"--{bad.path.split('.')[0].replace('_', '-')}: must be {bad.what}, got {shown(bad.value)}"
        ) from None


def schema() -> dict:
    """The results record as JSON Schema (draft 2020-12): the rules check_record
    applies, from the same checkers; one line of a results file is one record.
    The rules JSON Schema cannot state: a test-7 series' lists are equally
    long; a record's version is the one this raybench reads; a summary's
    figures are in order (min <= p5 <= median <= p95 <= max, the mean
    between), its kept samples within its min and max, and of its median
    where all were kept; no text holds half a UTF-16 pair; and a whole
    number is written as one (800, not the 800.0 that JSON Schema's integer
    also takes)."""
    measured = {"allOf": [MEASURED.json, {"if": {"properties": {"suite": {"const": "test7"}}}, "then": SERIES.json}]}
    skipped = {"allOf": [SKIPPED.json, {"properties": {"suite": {"enum": list(CAPPED)}}}]}
    return {
        "$schema": "https://json-schema.org/draft/2020-12/schema",
        "$id": f"https://raybench.invalid/schema/results-v{VERSION}.json",
        "title": f"raybench results record, version {VERSION}",
        "description": "One line of a raybench results file (JSON Lines): one measured point, a point "
        "skipped, or a part timed apart (suite 'parts'). Fields not named are allowed, for newer writers.",
        "type": "object",
        "required": ["format", "version", "suite", "run"],
        "properties": {"format": {"const": FORMAT}, "version": {"const": VERSION}, "run": RUN.json},
        "if": {"properties": {"suite": {"const": "parts"}}},
        "then": PART.json,
        "else": {"allOf": [POINT.json, {"if": {"required": ["skipped"]}, "then": skipped, "else": measured}]},
        "$defs": {"plain": PLAIN},
    }
