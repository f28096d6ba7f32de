"""The report's data: results files read and checked, records grouped into
columns (machine and kernel, or the BVH), and the series every verdict, chart
and table is drawn from. Pure functions of plain lists of records, so the
rules that judge them can be tested on synthetic data."""

from __future__ import annotations

import json
import math
import warnings
from pathlib import Path

from ...errors import RaybenchError
from .. import results
from ..stats import linear_fit
from ..suites import CAPPED

DEVICE_NAMES = {"cpu": "CPU", "cuda": "GPU", "wgpu": "wgpu"}


# --- loading ---------------------------------------------------------------


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


# --- series: pure functions of a list of records -----------------------------


def median_ms(r: dict, prefer_kernel: bool = False) -> float:
    if prefer_kernel and r.get("kernel_ms"):
        return float(r["kernel_ms"]["median"])
    return float(r["frame_ms"]["median"])


def machine_of(records: list[dict]) -> dict:
    return records[0]["run"]["machine"] if records else {}


def _fit(x, y) -> dict | None:
    try:
        return linear_fit(x, y)
    except ValueError:
        return None


def thesis_series(records: list[dict]) -> list[dict]:
    """Tests 1-6: one series per (device, resolution), points sorted by sphere
    count, with the least-squares line of median frame time (and of kernel time
    where every point has one)."""
    groups: dict[tuple, list[dict]] = {}
    for r in records:
        if r["suite"] == "thesis":
            groups.setdefault((r["device"], r["width"], r["height"]), []).append(r)
    out = []
    for (device, w, h), rs in sorted(groups.items(), key=lambda kv: (kv[0][0], kv[0][1] * kv[0][2])):
        rs.sort(key=lambda r: r["spheres"])
        spheres = [r["spheres"] for r in rs]
        median = [r["frame_ms"]["median"] for r in rs]
        kernel = [r["kernel_ms"]["median"] for r in rs] if all(r.get("kernel_ms") for r in rs) else None
        test = rs[0].get("test")
        out.append(
            {
                "device": device,
                "width": w,
                "height": h,
                "test": test,
                "label": f"{w}x{h}" + (f" (test {test})" if test else ""),
                "spheres": spheres,
                "median": median,
                "p5": [r["frame_ms"]["p5"] for r in rs],
                "p95": [r["frame_ms"]["p95"] for r in rs],
                "kernel": kernel,
                "tests_per_s": [r.get("tests_per_s") for r in rs],
                "fit": _fit(spheres, median),
                "kernel_fit": _fit(spheres, kernel) if kernel else None,
            }
        )
    return out


def test7_series(records: list[dict]) -> list[dict]:
    """Test 7: per device (and size), the frame time of every frame after the first."""
    out = []
    for r in records:
        if r["suite"] != "test7":
            continue
        s = r["series"]
        kernel = s.get("kernel_ms")
        if not (isinstance(kernel, list) and len(kernel) == len(s["spheres"])):
            kernel = None
        out.append(
            {
                "device": r["device"],
                "width": r["width"],
                "height": r["height"],
                "label": f"test 7 {DEVICE_NAMES.get(r['device'], r['device'])} {r['width']}x{r['height']}",
                "spheres": list(s["spheres"]),
                "frame_ms": list(s["frame_ms"]),
                "kernel_ms": kernel,
                "first_frame_s": r.get("first_frame_s"),
                "compile_s": r.get("compile_s"),
                "fit": _fit(s["spheres"], s["frame_ms"]),
            }
        )
    out.sort(key=lambda s: (s["device"], s["width"] * s["height"]))
    return out


def speedups(records: list[dict]) -> list[dict]:
    """Tests 1-6 matched by (width, height, spheres): CPU median frame time /
    GPU median frame time, sorted by resolution then sphere count."""
    by = {"cpu": {}, "cuda": {}}
    for r in records:
        if r["suite"] == "thesis" and r["device"] in by:
            by[r["device"]][(r["width"], r["height"], r["spheres"])] = r["frame_ms"]["median"]
    out = []
    for key in sorted(set(by["cpu"]) & set(by["cuda"]), key=lambda k: (k[0] * k[1], k[2])):
        cpu, gpu = by["cpu"][key], by["cuda"][key]
        out.append(
            {
                "width": key[0],
                "height": key[1],
                "spheres": key[2],
                "cpu_ms": cpu,
                "cuda_ms": gpu,
                "speedup": cpu / gpu if gpu > 0 else math.inf,
            }
        )
    return out


def theoretical_ratio(machine: dict) -> float | None:
    """GPU FP32 GFLOP/s / CPU FP32 GFLOP/s of the first GPU, or None if either is unknown."""
    cpu = (machine.get("cpu") or {}).get("fp32_gflops")
    gpus = machine.get("gpus") or []
    gpu = gpus[0].get("fp32_gflops") if gpus else None
    if not cpu or not gpu:
        return None
    return float(gpu) / float(cpu)


def largest_group(records: list[dict], suite: str, device: str) -> tuple[list[dict], int]:
    """The records of one suite and device at its largest workload (a quick and a
    full run merged under one label measure different sizes), and how many
    other groups were left out."""
    groups: dict[tuple, list[dict]] = {}
    for r in records:
        if r["suite"] == suite and r["device"] == device:
            groups.setdefault((r["width"], r["height"], r["spheres"]), []).append(r)
    if not groups:
        return [], 0
    key = max(groups, key=lambda k: (k[0] * k[1] * k[2], k))
    return groups[key], len(groups) - 1


def cpu_tuning(records: list[dict]) -> list[dict]:
    """CPU thread settings, fewest threads first: label, threads, median frame ms."""
    rs, _ = largest_group(records, "tuning", "cpu")
    out = [
        {
            "label": (r.get("options") or {}).get("label") or f"{(r.get('options') or {}).get('threads')} threads",
            "threads": (r.get("options") or {}).get("threads"),
            "ms": median_ms(r),
            "width": r["width"],
            "height": r["height"],
            "spheres": r["spheres"],
        }
        for r in rs
    ]
    return sorted(out, key=lambda e: (e["threads"] if isinstance(e["threads"], int) else 0, e["label"]))


def gpu_tuning(records: list[dict], device: str = "cuda") -> list[dict]:
    """GPU block shapes (wgpu: workgroup shapes) in the order measured: label
    ("32x32"), block, frame and kernel median ms, and ms, the time judged
    (kernel where measured)."""
    rs, _ = largest_group(records, "tuning", device)
    # kernel times only if every shape has one: a simulator run merged with a
    # real one must not pit one shape's kernel time against another's frame time
    kernel = all(r.get("kernel_ms") for r in rs)
    out = []
    for r in rs:
        opts = r.get("options") or {}
        block = opts.get("workgroup" if device == "wgpu" else "block")
        label = f"{block[0]}x{block[1]}" if isinstance(block, list) and len(block) == 2 else opts.get("label", "?")
        out.append(
            {
                "label": label,
                "block": block,
                "frame_ms": median_ms(r),
                "kernel_ms": r["kernel_ms"]["median"] if r.get("kernel_ms") else None,
                "ms": median_ms(r, prefer_kernel=kernel),
                "width": r["width"],
                "height": r["height"],
                "spheres": r["spheres"],
            }
        )
    return out


def constant_vs_runtime(records: list[dict], device: str) -> list[dict]:
    """Per (size, sphere count) measured both ways: constant and runtime median
    ms and runtime / constant. On the GPU kernel times are compared where both
    points have them ("timing": "kernel"), else frame times."""
    pairs: dict[tuple, dict] = {}
    for r in records:
        if r["suite"] == "constant-vs-runtime" and r["device"] == device:
            mode = (r.get("options") or {}).get("count")
            if mode in ("constant", "runtime"):
                pairs.setdefault((r["width"], r["height"], r["spheres"]), {})[mode] = r
    out = []
    for (w, h, n), pair in sorted(pairs.items(), key=lambda kv: (kv[0][0] * kv[0][1], kv[0][2])):
        if len(pair) < 2:
            continue
        kernel = all(p.get("kernel_ms") for p in pair.values())
        const, run = median_ms(pair["constant"], kernel), median_ms(pair["runtime"], kernel)
        out.append(
            {
                "width": w,
                "height": h,
                "spheres": n,
                "constant": const,
                "runtime": run,
                "ratio": run / const if const > 0 else math.inf,
                "timing": "kernel" if kernel else "frame",
            }
        )
    return out


def way_of(r: dict) -> str:
    if accel_of(r) == "bvh":
        opts = r.get("options") or {}
        way = f"BVH, {opts['tree_width']}-wide tree" if opts.get("tree_width") else "BVH"  # the cpu's, where chosen
        if opts.get("build") == "gpu":
            way += ", built on the GPU" + (f" ({opts['quality']})" if opts.get("quality") else "")
        return way + (f", {opts['walk']} walk" if opts.get("walk") else "")
    return f"brute force, {kernel_of(r)} kernel"


def scaling_series(records: list[dict]) -> list[dict]:
    """The scaling suite: one series per (device, way of tracing, size, scene
    layout), points sorted by sphere count; each point's median frame (and
    kernel) ms, rays/s and build s, or the reason it was skipped."""
    out: dict[tuple, dict] = {}
    for r in records:
        if r["suite"] != "scaling":
            continue
        layout = (r.get("options") or {}).get("layout")
        way = way_of(r) + (f", {layout} scene" if layout else "")
        key = (r["device"], way, r["width"], r["height"])
        s = out.setdefault(
            key,
            {
                "device": r["device"],
                "way": way,
                "accel": accel_of(r),
                "width": r["width"],
                "height": r["height"],
                "points": [],
            },
        )
        s["points"].append(
            {
                "spheres": r["spheres"],
                "skipped": r.get("skipped"),
                "median": None if "skipped" in r else float(r["frame_ms"]["median"]),
                "kernel": (r.get("kernel_ms") or {}).get("median"),
                "rays_per_s": r.get("rays_per_s"),
                "build_s": r.get("build_s"),
            }
        )
    for s in out.values():
        s["points"].sort(key=lambda p: p["spheres"])
    return sorted(out.values(), key=lambda s: (s["device"], s["way"], s["width"] * s["height"]))


def dynamic_points(records: list[dict]) -> list[dict]:
    """The dynamic suite: one row per measured point (device, where its tree
    is built, size, spheres): frames a second from the median frame, the
    median frame, update and kernel ms, the updates' share of the frames'
    time, and how many frames refitted and rebuilt. Sorted by spheres, then
    device and build."""
    out = []
    for r in records:
        if r["suite"] != "dynamic" or "skipped" in r:
            continue
        build = (r.get("options") or {}).get("build", "host")
        if (r.get("options") or {}).get("policy"):  # benchmarks/gpu_build.py's update policies
            build += f" ({r['options']['policy']})"
        out.append(
            {
                "device": r["device"],
                "build": build,
                "width": r["width"],
                "height": r["height"],
                "spheres": r["spheres"],
                "frames_per_s": 1e3 / float(r["frame_ms"]["median"]),
                "frame_ms": float(r["frame_ms"]["median"]),
                "update_ms": float((r.get("update_ms") or {}).get("median", 0.0)),
                "kernel_ms": (r.get("kernel_ms") or {}).get("median"),
                "update_share": r.get("update_share"),
                "updates": dict(r.get("updates") or {}),
            }
        )
    return sorted(out, key=lambda p: (p["spheres"], p["width"] * p["height"], p["device"], p["build"]))


def shading_of(r: dict) -> str:
    """A record's shading: "whitted" for the secondary suite's Whitted frames,
    else the thesis's (every record from before Whitted shading)."""
    return (r.get("options") or {}).get("shading", "thesis")


def secondary_points(records: list[dict]) -> list[dict]:
    """The secondary suite, one entry per (device, way of tracing, size, sphere
    count): "whitted" and "primary" (its thesis-shading twin), each with the
    median frame (and kernel) ms, rays/s, and for Whitted the rays by kind;
    None where that record is missing, and "skipped" the reason where the
    point was not measured. Sorted by device, way, size, count."""
    out: dict[tuple, dict] = {}
    for r in records:
        if r["suite"] != "secondary":
            continue
        key = (r["device"], way_of(r), r["width"], r["height"], r["spheres"])
        entry = out.setdefault(
            key,
            {
                "device": r["device"],
                "way": way_of(r),
                "accel": accel_of(r),
                "width": r["width"],
                "height": r["height"],
                "spheres": r["spheres"],
                "whitted": None,
                "primary": None,
            },
        )
        opts = r.get("options") or {}
        figures = {
            "skipped": r.get("skipped"),
            "median": None if "skipped" in r else float(r["frame_ms"]["median"]),
            "kernel": (r.get("kernel_ms") or {}).get("median"),
            "rays_per_s": r.get("rays_per_s"),
            "kernel_rays_per_s": r.get("kernel_rays_per_s"),
            "rays": r.get("rays"),
            "depth": opts.get("depth"),
            "shadow_samples": opts.get("shadow_samples"),
        }
        entry["whitted" if shading_of(r) == "whitted" else "primary"] = figures
    return sorted(out.values(), key=lambda e: (e["device"], e["way"], e["width"] * e["height"], e["spheres"]))


def _measured(figures: dict | None) -> bool:
    return bool(figures) and figures["median"] is not None and bool(figures["rays_per_s"])


def secondary_leads(records: list[dict], gpu: str = "cuda") -> list[dict]:
    """The points of the secondary suite that both the CPU and `gpu` measured
    with both shadings, matched by way of tracing, size and sphere count:
    the GPU's lead on secondary rays (GPU rays/s / CPU rays/s of the Whitted
    frames, every ray counted, median frames), on primary rays (the same of
    the thesis-shading twins), and kept, the first over the second."""
    by = {(p["device"], p["way"], p["width"], p["height"], p["spheres"]): p for p in secondary_points(records)}
    out = []
    for (device, way, w, h, n), cpu in by.items():
        other = by.get((gpu, way, w, h, n))
        if device != "cpu" or other is None:
            continue
        if not all(_measured(p[kind]) for p in (cpu, other) for kind in ("whitted", "primary")):
            continue
        secondary = other["whitted"]["rays_per_s"] / cpu["whitted"]["rays_per_s"]
        primary = other["primary"]["rays_per_s"] / cpu["primary"]["rays_per_s"]
        out.append(
            {
                "way": way,
                "accel": cpu["accel"],
                "width": w,
                "height": h,
                "spheres": n,
                "cpu_rays_per_s": cpu["whitted"]["rays_per_s"],
                "gpu_rays_per_s": other["whitted"]["rays_per_s"],
                "secondary": secondary,
                "primary": primary,
                "kept": secondary / primary,
            }
        )
    return out


def multi_gpu_series(records: list[dict]) -> list[dict]:
    """The multi-gpu suite, one series per (device, job, size, spheres): its
    points by worker count, each with its throughput (frames/s), the speedup
    over one worker of the series and the efficiency against linear
    (speedup / workers); both None where the series has no one-worker point."""
    out: dict[tuple, dict] = {}
    for r in records:
        if r["suite"] != "multi-gpu" or "skipped" in r:
            continue
        opts = r.get("options") or {}
        # delivery (benchmarks/multi_gpu.py's): how a job's frames came back, where it says
        key = (r["device"], opts.get("job"), opts.get("delivery"), r["width"], r["height"], r["spheres"],
               opts.get("frames"))  # fmt: skip
        s = out.setdefault(
            key,
            {"device": r["device"], "job": opts.get("job"), "delivery": opts.get("delivery"), "width": r["width"],
             "height": r["height"],
             "spheres": r["spheres"], "frames": opts.get("frames"), "points": []},
        )  # fmt: skip
        fps = 1e3 / float(r["frame_ms"]["median"])
        s["points"].append({"workers": int(opts.get("workers", 1)), "frames_per_s": fps})
    for s in out.values():
        s["points"].sort(key=lambda p: p["workers"])
        one = next((p["frames_per_s"] for p in s["points"] if p["workers"] == 1), None)
        s["one"] = one
        for p in s["points"]:
            p["speedup"] = p["frames_per_s"] / one if one else None
            p["efficiency"] = p["speedup"] / p["workers"] if one else None
    return sorted(out.values(), key=lambda s: (s["device"], s["job"] or "", s["width"] * s["height"]))


def parts_rows(records: list[dict]) -> list[dict]:
    """The parts suite: one row per quantity timed (results.PART), in the order
    measured: what, on which device, of what scene, and its time and figures."""
    return [
        {
            "quantity": r["quantity"],
            "device": r["device"],
            "spheres": r.get("spheres"),
            "size": f"{r['width']}x{r['height']}" if "width" in r and "height" in r else None,
            "options": r.get("options") or {},
            "time_ms": r["time_ms"],
            "samples": r.get("samples"),
            "values": r.get("values") or {},
        }
        for r in records
        if r["suite"] == "parts"
    ]
