"""The report's records: results files read and checked, a point measured
twice kept once (the later run's), and records grouped into columns (machine
and kernel, or the BVH)."""

from __future__ import annotations

import json
import math
import warnings
from pathlib import Path

from ...errors import RaybenchError
from .. import results
from ..suites import CAPPED


def _bad(path, number, what):
    raise RaybenchError(f"{path}: record {number}: {what}; not a complete raybench result")


def _check(record: dict, path, number: int) -> None:
    """The fields the report reads, so a hand-edited file fails with a line, not a traceback."""
    for key in ("suite", "device"):
        if not isinstance(record.get(key), str):
            _bad(path, number, f"field {key!r} missing")
    if record["suite"] == "parts":  # a quantity timed apart (results.PART): its own table
        stats = record.get("time_ms")
        if not isinstance(stats, dict) or not all(
            isinstance(stats.get(k), (int, float)) for k in ("median", "p5", "p95")
        ):
            _bad(path, number, "field 'time_ms' lacks median/p5/p95")
        if not isinstance(record.get("run"), dict) or not isinstance(record["run"].get("label"), str):
            _bad(path, number, "field 'run' lacks label or machine")
        return
    for key in ("width", "height", "spheres"):
        if not isinstance(record.get(key), int):
            _bad(path, number, f"field {key!r} missing or not a whole number")
    if "skipped" in record:  # a point not measured (a capped suite's, suites.CAPPED): only why
        if not isinstance(record["skipped"], str) or record["suite"] not in CAPPED:
            _bad(path, number, f"field 'skipped' is not a reason, or not in the {' or '.join(CAPPED)} suite")
        if not isinstance(record.get("run"), dict) or not isinstance(record["run"].get("label"), str):
            _bad(path, number, "field 'run' lacks label or machine")
        return
    for key in ("frame_ms", "kernel_ms"):
        stats = record.get(key)
        if stats is None and key == "kernel_ms":
            continue
        if not isinstance(stats, dict) or not all(
            isinstance(stats.get(k), (int, float)) for k in ("median", "p5", "p95")
        ):
            _bad(path, number, f"field {key!r} lacks median/p5/p95")
        # every ratio in the report divides by a time; a real frame never takes 0 ms
        if not all(math.isfinite(stats[k]) and stats[k] > 0 for k in ("median", "p5", "p95")):
            _bad(path, number, f"field {key!r} has a time that is not a positive number")
    if not isinstance(record.get("options", {}), dict):
        _bad(path, number, "field 'options' is not an object")
    run = record.get("run")
    if not isinstance(run, dict) or not isinstance(run.get("label"), str) or not isinstance(run.get("machine"), dict):
        _bad(path, number, "field 'run' lacks label or machine")
    if record["suite"] == "test7":
        series = record.get("series")
        if (
            not isinstance(series, dict)
            or not isinstance(series.get("spheres"), list)
            or not isinstance(series.get("frame_ms"), list)
            or len(series["spheres"]) != len(series["frame_ms"])
        ):
            _bad(path, number, "test7 'series' missing or its lists differ in length")


def _point_key(r: dict) -> tuple:
    return (
        r["suite"],
        r.get("test"),
        r.get("quantity"),
        r["device"],
        r.get("width"),
        r.get("height"),
        r.get("spheres"),
        json.dumps(r.get("options") or {}, sort_keys=True),
    )


def _read_all(paths, notes: list[str], sources: list) -> list[tuple]:
    """(path, records) of every results file named, or found under a folder
    named (its *.jsonl files, in sorted order, at any depth). A file named is
    read or refused; a file found in a folder that is not a raybench results
    file (another tool's, a damaged one) is skipped with a warning each."""
    out = []
    for given in paths:
        given = Path(given)
        found = given.is_dir()
        files = sorted(p for p in given.rglob("*.jsonl") if p.is_file()) if found else [given]
        for path in files:
            with warnings.catch_warnings(record=True) as caught:
                warnings.simplefilter("always")
                try:
                    records = results.read(path)
                except RaybenchError as exc:
                    if not found:
                        raise
                    caught.append(warnings.WarningMessage(f"skipped {exc}", UserWarning, __file__, 0))
                    records = None
            for w in caught:
                notes.append(str(w.message))
                warnings.warn(w.message, stacklevel=3)
            if records is not None:
                out.append((path, records))
                sources.append(path)
        if found and not files:
            raise RaybenchError(f"{given}: a folder holding no .jsonl results files")
    if not out:
        raise RaybenchError(f"{', '.join(map(str, paths))}: no raybench results among the files found")
    return out


def load(paths, sources: list | None = None) -> tuple[dict[str, list[dict]], list[str]]:
    """Read every results file (or every one under a folder: _read_all); return
    ({column: records}, notes), a column being a machine label and a kernel
    (column()). Columns keep the order they are first seen in. A point measured
    twice under one label keeps the later run's record (by run date, then file
    order). A half-written last line is skipped with a warning (results.read),
    also listed in notes; so is a foreign file in a folder. sources, if given,
    receives the path of every file read."""
    paths = list(paths)
    if not paths:
        raise RaybenchError("report: no results files given")
    notes: list[str] = []
    machines: dict[str, dict[tuple, dict]] = {}
    for path, records in _read_all(paths, notes, [] if sources is None else sources):
        for number, record in enumerate(records, 1):
            _check(record, path, number)
            points = machines.setdefault(column(record), {})
            key = _point_key(record)
            old = points.get(key)
            if old is not None:
                notes.append(
                    f"{column(record)}: {_describe_point(record)} was measured more than "
                    "once; the later run's record is used"
                )
                if str(old["run"].get("date")) > str(record["run"].get("date")):
                    continue
            points[key] = record
    return {label: list(points.values()) for label, points in machines.items()}, notes


def accel_of(record: dict) -> str:
    """How a record found the nearest sphere: "bvh", or "none" (brute force,
    every sphere), which records from before the BVH were measured with."""
    return (record.get("options") or {}).get("accel", "none")


def kernel_of(record: dict) -> str:
    """The kernel a record was measured with; records from before the fast
    kernel existed carry none and were measured with the simple one."""
    return (record.get("options") or {}).get("kernel", "simple")


def column(record: dict) -> str:
    """The report's column of a record: its machine and kernel (or the BVH),
    judged apart, since the thesis's claims mean something different for each."""
    if accel_of(record) == "bvh":
        return f"{record['run']['label']}, BVH"
    return f"{record['run']['label']}, {kernel_of(record)} kernel"


def group(records: list[dict]) -> dict[str, list[dict]]:
    """Records by column(), in the order the columns are first seen."""
    out: dict[str, list[dict]] = {}
    for r in records:
        out.setdefault(column(r), []).append(r)
    return out


def _describe_point(r: dict) -> str:
    opts = ", ".join(f"{k} {fmt_opt(v)}" for k, v in (r.get("options") or {}).items())
    what = f"{r['suite']} {r['quantity']}" if r["suite"] == "parts" else r["suite"]
    size = f" {r['width']}x{r['height']}" if "width" in r and "height" in r else ""
    spheres = f" {r['spheres']} spheres" if "spheres" in r else ""
    return f"{what} {r['device']}{size}{spheres}" + (f" ({opts})" if opts else "")


def fmt_opt(v) -> str:
    return "x".join(map(str, v)) if isinstance(v, (list, tuple)) else str(v)
