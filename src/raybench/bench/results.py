"""Benchmark results as JSON Lines: one record per measured point, appended and
flushed to disk as soon as the point finishes, so an interrupted run keeps
every point it finished.

A record (format "raybench-results", version 1):

    suite        "thesis" | "test7" | "constant-vs-runtime" | "tuning" | "scaling" | "secondary"
    test         the thesis's test number (1-3 GPU, 4-6 CPU by resolution; 7 the ramp), else null
    device       "cpu" | "cuda"
    width, height, spheres
    options      the device options used: {"threads": N} (cpu) or {"block": [x, y]} (cuda),
                 and for constant-vs-runtime {"count": "constant" | "runtime"};
                 tuning points carry "label", e.g. "2x cores" or "one per row";
                 "accel": "bvh" | "none" (absent in older records: none), "kernel"
                 for brute force; scaling's and secondary's brute-force points carry "cap_s";
                 secondary's points carry "shading": "thesis" (primary rays, the baseline) or
                 "whitted" with "depth" and "shadow_samples" (the materials scene,
                 random_spheres(n, seed, materials=True))
    frames       how many timed frames
    frame_ms     {mean, median, p5, p95, min, max}: whole frame (kernel, and on the GPU the copy to the host)
    kernel_ms    the same for the kernel alone (CUDA events), or null on the CPU
    rays_per_s, tests_per_s   from the median frame (tests = rays x spheres; null for the BVH);
                 under Whitted shading rays_per_s counts every ray cast, and tests_per_s is null
    rays         Whitted points only: the rays a frame cast by kind, as the kernel counted them,
                 {"primary", "shadow", "reflection", "refraction"}; rays_per_frame their sum;
                 kernel_rays_per_s the same rays over the median kernel time, or null
    build_s      the BVH's build time (seconds, compiled code only), or null for brute force
    first_frame_s   the first frame of the point, never averaged in
    compile_s       compiling the kernel for the point, if it was not yet compiled, else 0
    series       test7 only: {"spheres": [...], "frame_ms": [...], "kernel_ms": [... or null]},
                 one entry per frame after the first
    skipped      instead of frames, frame_ms, ...: why the point was not measured (the
                 scaling and secondary suites' brute force), e.g.
                 "predicted 4.2 s a frame, over the 1 s cap", with predicted_ms
    run          {"id", "date", "git_commit", "label", "argv", "settings", "machine": raybench.machine.describe()}
"""

from __future__ import annotations

import json
import os
import warnings
from pathlib import Path

from ..errors import RaybenchError
from ..files import read_text

FORMAT = "raybench-results"
VERSION = 1


class ResultsWriter:
    """Appends records to a .jsonl file, each on disk before the next point starts."""

    def __init__(self, path):
        self.path = Path(path)
        folder = self.path.parent
        try:
            folder.mkdir(parents=True, exist_ok=True)
            self._file = open(self.path, "a", encoding="utf-8")
        except OSError as exc:
            raise RaybenchError(f"{self.path}: cannot write results ({exc.strerror or exc})") from None
        self.count = 0

    def write(self, record: dict) -> None:
        line = json.dumps({"format": FORMAT, "version": VERSION, **record}, separators=(",", ":"))
        # One write of a whole line, then fsync: a crash can at worst leave a
        # half line at the end, which the reader skips with a warning.
        self._file.write(line + "\n")
        self._file.flush()
        os.fsync(self._file.fileno())
        self.count += 1

    def close(self) -> None:
        self._file.close()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()


def read(path) -> list[dict]:
    """All records of one results file. A half-written last line is skipped
    with a warning; a file that is not ours, or damaged before its end, is an
    error naming the line."""
    path = Path(path)
    text = read_text(path, "results file")
    lines = text.split("\n")
    records = []
    for number, line in enumerate(lines, 1):
        if not line.strip():
            continue
        last = number == len(lines) or all(not rest.strip() for rest in lines[number:])
        try:
            record = json.loads(line)
        except json.JSONDecodeError:
            if last and not text.endswith("\n"):
                warnings.warn(f"{path}: line {number} is cut short (an interrupted run?); skipped it", stacklevel=2)
                continue
            raise RaybenchError(f"{path}: line {number} is not JSON: not a raybench results file, or damaged") from None
        if not isinstance(record, dict) or record.get("format") != FORMAT:
            raise RaybenchError(f"{path}: line {number} is not a raybench result (format {FORMAT!r} expected)")
        if record.get("version") != VERSION:
            raise RaybenchError(
                f"{path}: line {number} has results version {record.get('version')!r}; "
                f"this raybench reads version {VERSION}"
            )
        records.append(record)
    if not records:
        raise RaybenchError(f"{path}: holds no results")
    return records
