"""The report: results files in, one Markdown file with PNG plots out, and a
verdict on each of the thesis's claims for every machine measured.

Records are grouped by machine and kernel (column()); files with the same
label are merged. Everything the verdicts depend on is computed by the small
pure functions below (speedups, thesis_series, test7_series, cpu_tuning,
gpu_tuning, constant_vs_runtime, verdicts), which take plain lists of records,
so the rules can be tested on synthetic data. The thresholds are the module
constants just below; RULES states them in words, and the report prints it.

Plots are drawn on matplotlib Figure objects with the Agg canvas attached
explicitly: no pyplot, no display, no global backend switch.
"""

from __future__ import annotations

import io
import json
import math
import re
import statistics
import warnings
from pathlib import Path

from ..errors import RaybenchError
from ..files import write_atomic
from . import results
from .stats import linear_fit

HOLDS, FAILS, NOT_MEASURED = "holds", "does not hold", "not measured"

THESIS_SPEEDUP = (58.0, 60.0)  # "between 58 and 60 times faster"
THESIS_CPU = "Intel Core i5 750 (4 cores, 2.67 GHz)"
THESIS_GPU = "Radeon HD 5770 (800 cores, 850 MHz)"
THESIS_RATIO = (800 * 0.85) / (4 * 2.67)  # the thesis's "about 64": cores x GHz, no SIMD
R2_MIN = 0.98  # claim 2: every series at least this linear
RATIO_BAND = (2 / 3, 3 / 2)  # claim 3: measured / theoretical speedup inside this band
NEAR_FASTEST = 1.05  # claims 4, 5: "within 5% of the fastest"
RUNTIME_SLOWER = 1.02  # claim 6: runtime / constant above this at every count

DEVICE_NAMES = {"cpu": "CPU", "cuda": "GPU", "wgpu": "wgpu"}

CLAIMS = [
    (
        "The GPU is faster than the CPU in every test (thesis: 58 to 60 times)",
        "58-60x faster in every test (tests 1-6, Radeon HD 5770 against Core i5 750)",
    ),
    (
        "Frame time grows linearly with the sphere count",
        '"all the results are linear" (charts of tests 1-7; no fit given)',
    ),
    (
        "The speedup is close to the ratio of the processors' theoretical compute rates "
        "(thesis: about 60 against about 64)",
        f"58-60x measured against {THESIS_RATIO:.0f}x computed as (800 cores x 0.85 GHz) / (4 cores x 2.67 GHz)",
    ),
    (
        "The largest thread groups (32x32) are fastest on the GPU",
        "time fell at every step from 2x2 to 32x32 threads per group (1024x768); 32x32 kept",
    ),
    (
        "About twice as many threads as cores is best on the CPU; one thread per row is worse than none",
        "8 threads on 4 cores best (4 to 10 tried); 768 threads, one per row, slower than no threading",
    ),
    (
        "A sphere count that is a runtime variable is slower than a compile-time constant",
        "test 7's runtime nrOfSpheres is slower than the constant count of tests 1-6 (no number given)",
    ),
]

RULES = [
    "All speedups are CPU median frame time / GPU median frame time at the same width, height and "
    'sphere count (suite thesis, tests 1-6); a verdict is "not measured" when the data it needs are missing.',
    "1. Holds if every matched speedup is above 1.",
    f"2. Each series (device x resolution of tests 1-6: median frame time against spheres; test 7: every "
    f"frame) gets a least-squares line; holds if every R² >= {R2_MIN}.",
    f"3. Holds if the median speedup divided by the machine's theoretical ratio (GPU FP32 GFLOP/s / CPU "
    f"FP32 GFLOP/s, from the machine description) is between {RATIO_BAND[0]:.2f} and {RATIO_BAND[1]:.2f}.",
    f"4. GPU tuning: holds if 32x32's median time (kernel time where measured, else frame time) is at most "
    f"{NEAR_FASTEST:.2f} x that of the fastest block shape.",
    f'5. CPU tuning (median frame time): holds if "2x cores" is at most {NEAR_FASTEST:.2f} x the fastest '
    f'setting AND "one per row" is slower than "1 thread"; each half is reported on its own.',
    f"6. Holds if, on the GPU, runtime / constant median time (kernel time where measured) is above "
    f"{RUNTIME_SLOWER} at every sphere count measured; the CPU's ratios are shown for information only.",
]


# --- loading ---------------------------------------------------------------


def _bad(path, number, what):
    raise RaybenchError(f"{path}: record {number}: {what}; not a complete raybench result")


def _check(record: dict, path, number: int) -> None:
    """The fields the report reads, so a hand-edited file fails with a line, not a traceback."""
    for key in ("suite", "device"):
        if not isinstance(record.get(key), str):
            _bad(path, number, f"field {key!r} missing")
    for key in ("width", "height", "spheres"):
        if not isinstance(record.get(key), int):
            _bad(path, number, f"field {key!r} missing or not a whole number")
    if "skipped" in record:  # a point not measured (the scaling suite's cap): only why
        if not isinstance(record["skipped"], str) or record["suite"] != "scaling":
            _bad(path, number, "field 'skipped' is not a reason, or not in the scaling suite")
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
        r["device"],
        r["width"],
        r["height"],
        r["spheres"],
        json.dumps(r.get("options") or {}, sort_keys=True),
    )


def load(paths) -> tuple[dict[str, list[dict]], list[str]]:
    """Read every results file; return ({column: records}, notes), a column
    being a machine label and a kernel (column()). Columns keep
    the order they are first seen in. A point measured twice under one label
    keeps the later run's record (by run date, then file order). A half-written
    last line is skipped with a warning (results.read), also listed in notes."""
    paths = list(paths)
    if not paths:
        raise RaybenchError("report: no results files given")
    notes: list[str] = []
    machines: dict[str, dict[tuple, dict]] = {}
    for path in paths:
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            records = results.read(path)
        for w in caught:
            notes.append(str(w.message))
            warnings.warn(w.message, stacklevel=2)
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
    opts = _text(", ".join(f"{k} {_fmt_opt(v)}" for k, v in (r.get("options") or {}).items()))
    return f"{r['suite']} {r['device']} {r['width']}x{r['height']} {r['spheres']} spheres" + (
        f" ({opts})" if opts else ""
    )


def _fmt_opt(v) -> str:
    return "x".join(map(str, v)) if isinstance(v, (list, tuple)) else str(v)


# --- analysis: pure functions of a list of records ---------------------------


def _median(r: dict, prefer_kernel: bool = False) -> float:
    if prefer_kernel and r.get("kernel_ms"):
        return float(r["kernel_ms"]["median"])
    return float(r["frame_ms"]["median"])


def _machine(records: list[dict]) -> dict:
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


def _largest_group(records: list[dict], suite: str, device: str) -> tuple[list[dict], int]:
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
    rs, _ = _largest_group(records, "tuning", "cpu")
    out = [
        {
            "label": (r.get("options") or {}).get("label") or f"{(r.get('options') or {}).get('threads')} threads",
            "threads": (r.get("options") or {}).get("threads"),
            "ms": _median(r),
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
    rs, _ = _largest_group(records, "tuning", device)
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
                "frame_ms": _median(r),
                "kernel_ms": r["kernel_ms"]["median"] if r.get("kernel_ms") else None,
                "ms": _median(r, prefer_kernel=kernel),
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
        const, run = _median(pair["constant"], kernel), _median(pair["runtime"], kernel)
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


def verdicts(records: list[dict]) -> list[dict]:
    """The six claims judged on one machine's records. Each entry: number,
    claim, thesis (what the thesis measured), verdict (HOLDS, FAILS or
    NOT_MEASURED), measured (one line of the numbers behind it) and values
    (those numbers, for tests and tables)."""
    found = [_claim1(records), _claim2(records), _claim3(records), _claim4(records), _claim5(records), _claim6(records)]
    out = []
    for number, ((claim, thesis), (verdict, measured, values)) in enumerate(zip(CLAIMS, found), 1):
        out.append(
            {
                "number": number,
                "claim": claim,
                "thesis": thesis,
                "verdict": verdict,
                "measured": measured,
                "values": values,
            }
        )
    return out


def _where(p: dict) -> str:
    return f"{p['width']}x{p['height']}, {p['spheres']} spheres"


def _claim1(records):
    sp = speedups(records)
    if not sp:
        return NOT_MEASURED, "needs tests 1-6 on both CPU and GPU", {}
    values = [p["speedup"] for p in sp]
    low = min(sp, key=lambda p: p["speedup"])
    slower = [p for p in sp if p["speedup"] <= 1]
    text = (
        f"min {_x(low['speedup'])} ({_where(low)}), median {_x(statistics.median(values))}, "
        f"max {_x(max(values))} over {len(sp)} matched points"
    )
    if slower:
        text += f"; the GPU is not faster at {len(slower)} of them"
    return (
        (FAILS if slower else HOLDS),
        text,
        {
            "min": min(values),
            "median": statistics.median(values),
            "max": max(values),
            "n": len(sp),
            "not_faster": len(slower),
        },
    )


def _claim2(records):
    fits = [(s["label"] + f" {DEVICE_NAMES.get(s['device'], s['device'])}", s["fit"]) for s in thesis_series(records)]
    fits += [(s["label"], s["fit"]) for s in test7_series(records)]
    fits = [(name, f) for name, f in fits if f is not None]
    if not fits:
        return NOT_MEASURED, "needs tests 1-6 or test 7 with at least two sphere counts", {}
    # R² is nan for a flat series; it counts as the least linear.
    name, worst = min(fits, key=lambda nf: -math.inf if math.isnan(nf[1]["r2"]) else nf[1]["r2"])
    r2 = worst["r2"]
    bad = [n for n, f in fits if not f["r2"] >= R2_MIN]
    text = f"lowest R² {_r2(r2)} ({name}) over {len(fits)} series"
    if bad:
        text += f"; {len(bad)} below {R2_MIN}"
    return (FAILS if bad else HOLDS), text, {"min_r2": r2, "series": name, "n": len(fits), "below": bad}


def _claim3(records):
    sp = speedups(records)
    ratio = theoretical_ratio(_machine(records))
    if not sp:
        return NOT_MEASURED, "needs tests 1-6 on both CPU and GPU", {"theoretical": ratio}
    median = statistics.median(p["speedup"] for p in sp)
    if ratio is None:
        return (
            NOT_MEASURED,
            f"median speedup {_x(median)}; the machine description lacks a CPU or GPU FP32 rate",
            {"median": median, "theoretical": None},
        )
    share = median / ratio
    ok = RATIO_BAND[0] <= share <= RATIO_BAND[1]
    text = f"median speedup {_x(median)} against theoretical {_x(ratio)}: {_num(share)} of it"
    return (HOLDS if ok else FAILS), text, {"median": median, "theoretical": ratio, "share": share}


def _claim4(records):
    shapes = gpu_tuning(records)
    big = next((s for s in shapes if s["label"] == "32x32"), None)
    if big is None:
        return NOT_MEASURED, "needs GPU tuning with a 32x32 block", {}
    fastest = min(shapes, key=lambda s: s["ms"])
    rel = big["ms"] / fastest["ms"]
    timing = "kernel" if all(s["kernel_ms"] is not None for s in shapes) else "frame"
    if fastest is big:
        text = f"32x32 is the fastest of {len(shapes)} shapes ({_ms(big['ms'])} ms {timing})"
    else:
        text = f"fastest {fastest['label']} ({_ms(fastest['ms'])} ms {timing}); 32x32 takes {_num(rel)}x as long"
    return (HOLDS if rel <= NEAR_FASTEST else FAILS), text, {"fastest": fastest["label"], "relative": rel}


def _claim5(records):
    settings = cpu_tuning(records)
    if not settings:
        return NOT_MEASURED, "needs CPU tuning", {}
    by = {s["label"]: s for s in settings}
    fastest = min(settings, key=lambda s: s["ms"])
    parts, values, verdicts_ = [], {"fastest": fastest["label"]}, []
    two = by.get("2x cores")
    if two:
        rel = two["ms"] / fastest["ms"]
        ok = rel <= NEAR_FASTEST
        values.update(two_x_relative=rel, two_x_ok=ok)
        verdicts_.append(ok)
        where = (
            "is the fastest"
            if two is fastest
            else (f"takes {_num(rel)}x the fastest ({fastest['label']}, {fastest['threads']} threads)")
        )
        parts.append(f"2x cores ({two['threads']} threads) {where}: {HOLDS if ok else FAILS}")
    else:
        parts.append("2x cores: not measured")
    one, row = by.get("1 thread"), by.get("one per row")
    if one and row:
        rel = row["ms"] / one["ms"]
        ok = rel > 1
        values.update(per_row_relative=rel, per_row_ok=ok)
        verdicts_.append(ok)
        parts.append(
            f"one per row ({row['threads']} threads) takes {_num(rel)}x the time of 1 thread: {HOLDS if ok else FAILS}"
        )
    else:
        parts.append("one per row vs 1 thread: not measured")
    if verdicts_ and not all(verdicts_):
        verdict = FAILS
    elif len(verdicts_) == 2:
        verdict = HOLDS
    else:
        verdict = NOT_MEASURED
    return verdict, "; ".join(parts), values


def _claim6(records):
    gpu, cpu = constant_vs_runtime(records, "cuda"), constant_vs_runtime(records, "cpu")

    def listing(rows):
        timing = "kernel" if rows and all(r["timing"] == "kernel" for r in rows) else "frame"
        return (
            f"{timing} time runtime/constant "
            + ", ".join(f"{_num(r['ratio'])} ({r['spheres']})" for r in rows)
            + " at (spheres)"
        )

    info = f"; CPU (information): {listing(cpu)}" if cpu else ""
    values = {"gpu": [r["ratio"] for r in gpu], "cpu": [r["ratio"] for r in cpu]}
    if not gpu:
        return NOT_MEASURED, "needs constant-vs-runtime on the GPU" + info, values
    ok = all(r["ratio"] > RUNTIME_SLOWER for r in gpu)
    return (HOLDS if ok else FAILS), f"GPU: {listing(gpu)}{info}", values


# --- formatting ----------------------------------------------------------------


def _num(x, sig: int = 3) -> str:
    """x to sig significant digits, never in exponent notation."""
    if x is None or (isinstance(x, float) and not math.isfinite(x)):
        return "–" if x is None or math.isnan(x) else ("∞" if x > 0 else "-∞")
    if x == 0:
        return "0"
    digits = max(0, sig - 1 - math.floor(math.log10(abs(x))))
    return f"{x:.{digits}f}"


def _ms(x) -> str:
    return _num(x, 3)


def _x(x) -> str:
    return f"{_num(x)}x"


def _r2(x) -> str:
    return "nan (flat)" if x is None or math.isnan(x) else f"{x:.4f}"


def _md(text) -> str:
    return str(text).replace("|", "\\|").replace("\n", " ")


_MARKDOWN = re.compile(r"([\\`*_\[\]<>&#$~!])")


def _text(value) -> str:
    """Text from a results file (a CPU's model, a driver, a setting), shown
    as the characters it holds: every character Markdown or HTML would act
    on is escaped, so a record cannot add a link, an image or a tag. A
    table cell still goes through _md for its "|"."""
    return _MARKDOWN.sub(r"\\\1", " ".join(str(value).split()))


def _table(header: list[str], rows: list[list]) -> str:
    lines = ["| " + " | ".join(_md(h) for h in header) + " |", "|" + "---|" * len(header)]
    lines += ["| " + " | ".join(_md(c) for c in row) + " |" for row in rows]
    return "\n".join(lines)


# --- plots -----------------------------------------------------------------------


def _figure(ncols: int = 1, width: float = 7.5, height: float = 4.6):
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=(width, height), dpi=110, layout="constrained")
    FigureCanvasAgg(fig)
    axes = fig.subplots(1, ncols, squeeze=False)[0]
    for ax in axes:
        ax.grid(True, alpha=0.3)
    return fig, list(axes)


def _png(fig) -> bytes:
    buf = io.BytesIO()
    fig.savefig(buf, format="png")
    return buf.getvalue()


def _linear_or_log(ax, values) -> None:
    values = [v for v in values if v and v > 0 and math.isfinite(v)]
    if values and max(values) / min(values) > 30:
        from matplotlib.ticker import ScalarFormatter

        ax.set_yscale("log")
        ax.yaxis.set_major_formatter(ScalarFormatter())
    else:
        ax.set_ylim(bottom=0)


def _plot_thesis(label: str, device: str, series: list[dict], device_name: str) -> bytes:
    from matplotlib.lines import Line2D
    from matplotlib.patches import Patch

    fig, (ax,) = _figure()
    any_kernel = False
    for i, s in enumerate(series):
        color = f"C{i}"
        ax.fill_between(s["spheres"], s["p5"], s["p95"], color=color, alpha=0.2, linewidth=0)
        ax.plot(s["spheres"], s["median"], "o-", color=color, markersize=4, label=s["label"])
        if s["fit"]:
            xs = [min(s["spheres"]), max(s["spheres"])]
            ax.plot(xs, [s["fit"]["slope"] * x + s["fit"]["intercept"] for x in xs], "--", color=color, linewidth=1)
        if s["kernel"]:
            any_kernel = True
            ax.plot(s["spheres"], s["kernel"], ":", color=color, linewidth=1.5)
    handles, labels = ax.get_legend_handles_labels()
    handles += [Line2D([], [], color="gray", linestyle="--"), Patch(color="gray", alpha=0.2)]
    labels += ["least-squares line", "p5-p95 of frames"]
    if any_kernel:
        handles.append(Line2D([], [], color="gray", linestyle=":", linewidth=1.5))
        labels.append("kernel only (CUDA events)")
    ax.legend(handles, labels, fontsize=8)
    tests = [s["test"] for s in series if s["test"]]
    what = f"tests {min(tests)}-{max(tests)}" if tests else "thesis tests"
    ax.set_title(f"{label}: {DEVICE_NAMES.get(device, device)} {what}, {device_name}", fontsize=10)
    ax.set_xlabel("spheres in the scene")
    ax.set_ylabel("median frame time (ms)")
    ax.set_ylim(bottom=0)
    ax.set_xlim(left=0)
    return _png(fig)


def _plot_speedup(label: str, sp: list[dict], ratio: float | None) -> bytes:
    fig, (ax,) = _figure()
    sizes = sorted({(p["width"], p["height"]) for p in sp}, key=lambda s: s[0] * s[1])
    for i, (w, h) in enumerate(sizes):
        pts = [p for p in sp if (p["width"], p["height"]) == (w, h)]
        ax.plot(
            [p["spheres"] for p in pts],
            [p["speedup"] for p in pts],
            "o-",
            color=f"C{i}",
            markersize=4,
            label=f"{w}x{h}",
        )
    ax.axhspan(*THESIS_SPEEDUP, color="gray", alpha=0.35, label="thesis: 58-60x")
    if ratio:
        ax.axhline(ratio, color="C3", linestyle="--", label=f"theoretical FP32 ratio: {_x(ratio)}")
    ax.axhline(1, color="black", linewidth=0.8, label="1x (no gain)")
    _linear_or_log(ax, [p["speedup"] for p in sp] + list(THESIS_SPEEDUP) + ([ratio] if ratio else []) + [1])
    ax.set_title(f"{label}: GPU speedup over the CPU (CPU frame time / GPU frame time)", fontsize=10)
    ax.set_xlabel("spheres in the scene")
    ax.set_ylabel("speedup (x)")
    ax.set_xlim(left=0)
    ax.legend(fontsize=8)
    return _png(fig)


def _plot_test7(label: str, series: list[dict]) -> bytes:
    fig, axes = _figure(len(series), width=4.2 * len(series) + 1, height=4.2)
    for i, (ax, s) in enumerate(zip(axes, series)):
        ax.plot(
            s["spheres"], s["frame_ms"], "-", color=f"C{i}", linewidth=1, marker=".", markersize=3, label="frame time"
        )
        if s["kernel_ms"]:
            ax.plot(s["spheres"], s["kernel_ms"], "-", color="gray", linewidth=0.8, label="kernel only")
        if s["fit"]:
            xs = [min(s["spheres"]), max(s["spheres"])]
            ax.plot(
                xs,
                [s["fit"]["slope"] * x + s["fit"]["intercept"] for x in xs],
                "--",
                color="black",
                linewidth=1,
                label=f"least squares (R² {_r2(s['fit']['r2'])})",
            )
        ax.set_title(f"{DEVICE_NAMES.get(s['device'], s['device'])}, {s['width']}x{s['height']}", fontsize=10)
        ax.set_xlabel("spheres in the scene (10 more each frame)")
        ax.set_ylabel("frame time (ms)")
        ax.set_ylim(bottom=0)
        ax.legend(fontsize=8)
    fig.suptitle(f"{label}: test 7, one frame per sphere count (first frame left out)", fontsize=10)
    return _png(fig)


def _bars(ax, labels, groups, names, ylabel, best=True):
    """Grouped bars: groups is a list (one per bar series) of values per label."""
    n = len(groups)
    width = 0.8 / n
    for j, (values, name) in enumerate(zip(groups, names)):
        xs = [i + (j - (n - 1) / 2) * width for i in range(len(labels))]
        bars = ax.bar(xs, values, width, label=name, color=f"C{j}")
        ax.bar_label(bars, [_ms(v) for v in values], fontsize=7, padding=1)
        if best and j == n - 1 and values:
            k = min(range(len(values)), key=values.__getitem__)
            bars[k].set_edgecolor("black")
            bars[k].set_linewidth(1.5)
    ax.set_xticks(range(len(labels)), labels, fontsize=8)
    ax.set_ylabel(ylabel)
    ax.margins(y=0.12)
    if n > 1 or names[0]:
        ax.legend(fontsize=8)


def _plot_tuning(label: str, cpu: list[dict], gpu: list[dict]) -> bytes:
    panels = [p for p in (("cpu", cpu), ("cuda", gpu)) if p[1]]
    fig, axes = _figure(len(panels), width=6.5 * len(panels), height=4.4)
    for ax, (device, rows) in zip(axes, panels):
        r0 = rows[0]
        where = f"{r0['width']}x{r0['height']}, {r0['spheres']} spheres"
        if device == "cpu":
            _bars(
                ax,
                [f"{r['label']}\n{r['threads']} thread{'s' if r['threads'] != 1 else ''}" for r in rows],
                [[r["ms"] for r in rows]],
                [""],
                "median frame time (ms)",
            )
            ax.set_title(f"CPU threads ({where})", fontsize=10)
        else:
            has_kernel = all(r["kernel_ms"] is not None for r in rows)
            groups = [[r["frame_ms"] for r in rows]] + ([[r["kernel_ms"] for r in rows]] if has_kernel else [])
            names = ["whole frame", "kernel only"] if has_kernel else ["whole frame"]
            _bars(ax, [r["label"] for r in rows], groups, names, "median time (ms)")
            ax.set_xlabel("threads per block (x by y)")
            ax.tick_params(axis="x", labelrotation=45)
            ax.set_title(f"GPU block shapes ({where})", fontsize=10)
    fig.suptitle(f"{label}: tuning (the fastest bar is outlined)", fontsize=10)
    return _png(fig)


def _plot_constant(label: str, rows_by_device: dict[str, list[dict]]) -> bytes:
    panels = [(d, rows) for d, rows in rows_by_device.items() if rows]
    fig, axes = _figure(len(panels), width=5.2 * len(panels) + 0.5, height=4.2)
    for ax, (device, rows) in zip(axes, panels):
        sizes = {(r["width"], r["height"]) for r in rows}
        names = [f"{r['spheres']}" if len(sizes) == 1 else f"{r['spheres']}\n{r['width']}x{r['height']}" for r in rows]
        timing = "kernel" if all(r["timing"] == "kernel" for r in rows) else "frame"
        _bars(
            ax,
            names,
            [[r["constant"] for r in rows], [r["runtime"] for r in rows]],
            ["constant (compile time)", "runtime variable"],
            f"median {timing} time (ms)",
            best=False,
        )
        ax.set_xlabel("spheres in the scene")
        where = f", {rows[0]['width']}x{rows[0]['height']}" if len(sizes) == 1 else ""
        ax.set_title(f"{DEVICE_NAMES.get(device, device)}{where}", fontsize=10)
    fig.suptitle(f"{label}: sphere count as a compile-time constant or a runtime variable", fontsize=10)
    return _png(fig)


# --- the report -----------------------------------------------------------------


def _slug(label: str, taken: set) -> str:
    slug = re.sub(r"[^A-Za-z0-9._-]+", "-", label).strip("-.") or "machine"
    base, i = slug, 2
    while slug in taken:
        slug, i = f"{base}-{i}", i + 1
    taken.add(slug)
    return slug


def _adapter_name(records: list[dict]) -> str:
    """The wgpu adapter of these records, e.g. "llvmpipe (...) (Vulkan, CPU)": a CPU driver must not pass for a GPU."""
    names = sorted(
        {
            f"{a.get('name')} ({a.get('backend')}, {a.get('type')})"
            for r in records
            if r["device"] == "wgpu" and isinstance(a := r.get("adapter"), dict)
        }
    )
    return ", ".join(names) or "unknown adapter"


def _gpu_name(machine: dict) -> str:
    gpus = machine.get("gpus") or []
    return gpus[0].get("name", "unknown GPU") if gpus else "no CUDA GPU"


def _machine_lines(label: str, records: list[dict]) -> list[str]:
    m = _machine(records)
    cpu = m.get("cpu") or {}
    versions = m.get("versions") or {}
    gpus = m.get("gpus") or []
    gpu = (
        (
            f"{_text(gpus[0].get('name'))} ({gpus[0].get('multiprocessors', '?')} multiprocessors, "
            f"{gpus[0].get('memory_gib', '?')} GiB, driver {_text(gpus[0].get('driver') or '?')})"
        )
        if gpus
        else "no CUDA GPU"
    )
    lines = [
        f"**{_md(label)}**: CPU {_text(cpu.get('model', '?'))} ({cpu.get('physical_cores', '?')} cores, "
        f"{cpu.get('logical_cpus', '?')} threads); GPU {gpu}; {_text(m.get('os', ''))}; "
        f"raybench {_text(versions.get('raybench') or '?')}, numba {_text(versions.get('numba') or '?')}, "
        f"numba-cuda {_text(versions.get('numba-cuda') or '?')}."
    ]
    runs = {}
    for r in records:
        runs.setdefault(r["run"].get("id"), (r["run"], []))[1].append(r)
    for run, rs in runs.values():
        settings = run.get("settings") or {}
        shown = _text(", ".join(f"{k} {_fmt_opt(v)}" for k, v in settings.items()))
        lines.append(
            f"- run {_text(run.get('id', '?'))}: {_text(run.get('date', '?'))}, "
            f"git {_text(run.get('git_commit') or 'unknown')}, "
            f"{len(rs)} points; settings: {shown or 'none recorded'}"
        )
    machines = {json.dumps(r["run"]["machine"].get("cpu"), sort_keys=True) for r in records}
    if len(machines) > 1:
        lines.append(
            "- note: the runs under this label describe different CPUs; the first run's machine is used "
            "for the theoretical rates"
        )
    return lines


def _rates_text(machine: dict) -> str:
    cpu = machine.get("cpu") or {}
    gpus = machine.get("gpus") or []
    parts = []
    if cpu.get("fp32_gflops"):
        parts.append(
            f"CPU {_num(cpu['fp32_gflops'])} GFLOP/s FP32 ({cpu.get('physical_cores', '?')} cores x "
            f"{cpu.get('clock_ghz', '?')} GHz x {cpu.get('fp32_lanes', '?')} {_text(cpu.get('simd') or '')} lanes x 2 "
            f"(multiply-add) x {cpu.get('fma_units_per_core', '?')} FMA units)"
        )
    else:
        parts.append("CPU FP32 rate unknown")
    if gpus and gpus[0].get("fp32_gflops"):
        g = gpus[0]
        parts.append(
            f"GPU {_num(g['fp32_gflops'])} GFLOP/s FP32 ({g.get('multiprocessors', '?')} multiprocessors x "
            f"{g.get('fp32_lanes_per_sm', '?')} lanes x 2 x {g.get('clock_ghz', '?')} GHz)"
        )
    else:
        parts.append("GPU FP32 rate unknown")
    ratio = theoretical_ratio(machine)
    text = "; ".join(parts) + (f": a theoretical ratio of **{_x(ratio)}**." if ratio else ".")
    return (
        text + f" (The thesis counted cores x GHz and no SIMD: {THESIS_GPU} against {THESIS_CPU} gives "
        f"{_num(THESIS_RATIO)}x. Counting the CPU's SIMD lanes, as these rates do, gives a far smaller ratio "
        "for the same two chips.)"
    )


class _Writer:
    """Collects the report's lines and writes each plot as soon as it is drawn."""

    def __init__(self, out_dir: Path):
        self.out_dir = out_dir
        self.lines: list[str] = []
        self.pngs: list[Path] = []

    def __call__(self, *lines: str) -> None:
        self.lines.extend(lines)

    def image(self, name: str, data: bytes, alt: str) -> None:
        path = self.out_dir / name
        write_atomic(path, data)
        self.pngs.append(path)
        self(f"![{alt}]({name})", "")


def _section_thesis(w: _Writer, label: str, slug: str, records: list[dict]) -> None:
    w("### Tests 1-6: frame time against sphere count", "")
    series = thesis_series(records)
    if not series:
        w("Not measured: these results hold no `thesis` suite (`raybench bench --suite thesis`).", "")
        return
    w(
        "Each chart shows one processor: the median time to render one frame (dots, solid line) for 100 to "
        "1000 spheres at each resolution, the spread of the frames from the 5th to the 95th percentile "
        "(shaded band, often thinner than the line), and the least-squares straight line (dashed). If the "
        "dots sit on the dashed line, frame time grows linearly with the number of spheres, as the thesis "
        "says. The slope is the cost of one more sphere for the whole picture; the intercept is the cost of "
        "a frame with no spheres (launch, copy, overhead). R² is 1 for a perfect line.",
        "",
    )
    machine = _machine(records)
    for device in ("cuda", "wgpu", "cpu"):
        ds = [s for s in series if s["device"] == device]
        if not ds:
            if device != "wgpu":  # the portable backend is news where measured, not a gap where not
                w(f"{DEVICE_NAMES[device]}: not measured.", "")
            continue
        name = (
            _gpu_name(machine)
            if device == "cuda"
            else _adapter_name(records)
            if device == "wgpu"
            else (machine.get("cpu") or {}).get("model", "CPU")
        )
        w(f"**{DEVICE_NAMES[device]}** ({_text(name)})", "")
        w.image(
            f"{slug}-thesis-{device}.png",
            # a "$" would start matplotlib's mathematics
            _plot_thesis(label, device, ds, str(name).replace("$", r"\$")),
            f"{label}: {DEVICE_NAMES[device]} frame time against spheres",
        )
        counts = sorted({n for s in ds for n in s["spheres"]})
        kernel = any(s["kernel"] for s in ds)
        header = ["resolution", "test", "slope (ms/sphere)", "intercept (ms)", "R²"] + [f"{n}" for n in counts]
        if kernel:
            header += ["kernel ms at max count", "kernel slope (ms/sphere)"]
        header += ["ray-sphere tests/s at max count"]
        rows = []
        for s in ds:
            f = s["fit"]
            at = dict(zip(s["spheres"], s["median"]))
            row = [
                f"{s['width']}x{s['height']}",
                s["test"] or "–",
                _num(f["slope"]) if f else "–",
                _num(f["intercept"]) if f else "–",
                _r2(f["r2"]) if f else "–",
            ]
            row += [_ms(at[n]) if n in at else "" for n in counts]
            if kernel:
                row += [
                    _ms(s["kernel"][-1]) if s["kernel"] else "–",
                    _num(s["kernel_fit"]["slope"]) if s["kernel_fit"] else "–",
                ]
            tps = s["tests_per_s"][-1]
            row.append(f"{_num(tps / 1e9)} G" if tps else "–")
            rows.append(row)
        w("Median frame time (ms) at each sphere count, and the line fitted to it:", "", _table(header, rows), "")


def _section_speedup(w: _Writer, label: str, slug: str, records: list[dict]) -> None:
    w("### GPU over CPU speedup", "")
    sp = speedups(records)
    machine = _machine(records)
    ratio = theoretical_ratio(machine)
    if not sp:
        w(
            "Not measured: this needs tests 1-6 on both the CPU and the GPU at the same resolutions and sphere counts.",
            "",
            f"Theoretical rates: {_rates_text(machine)}",
            "",
        )
        return
    w(
        "How many times faster the GPU renders the same frame than the CPU (CPU median frame time divided by "
        "GPU median frame time, whole frames including the GPU's copy back to the host). The grey band is the "
        "thesis's 58-60x; the red dashed line is what the two processors' peak FP32 rates would predict if both "
        "ran the ray tracer equally close to their peak.",
        "",
    )
    w(f"Theoretical rates: {_rates_text(machine)}", "")
    w.image(f"{slug}-speedup.png", _plot_speedup(label, sp, ratio), f"{label}: GPU speedup over CPU")
    counts = sorted({p["spheres"] for p in sp})
    sizes = sorted({(p["width"], p["height"]) for p in sp}, key=lambda s: s[0] * s[1])
    at = {(p["width"], p["height"], p["spheres"]): p["speedup"] for p in sp}
    rows = [[f"{wd}x{ht}"] + [_x(at[(wd, ht, n)]) if (wd, ht, n) in at else "" for n in counts] for wd, ht in sizes]
    w(_table(["resolution"] + [f"{n}" for n in counts], rows), "")


def _section_test7(w: _Writer, label: str, slug: str, records: list[dict]) -> None:
    w("### Test 7: adding ten spheres every frame", "")
    series = test7_series(records)
    if not series:
        w("Not measured: these results hold no test 7 (it runs with `--suite thesis`).", "")
        return
    w(
        "As in the thesis, the scene starts with 10 spheres and gets 10 more every frame up to 1000; each dot "
        "is one frame, with the sphere count passed to the kernel at run time. The very first frame is left "
        "out of the chart and the fit, because it includes setting everything up (its time is given below). "
        "Single frames are noisier than the medians of tests 1-6.",
        "",
    )
    w.image(f"{slug}-test7.png", _plot_test7(label, series), f"{label}: test 7 frame time against spheres")
    rows = []
    for s in series:
        f = s["fit"]
        rows.append(
            [
                DEVICE_NAMES.get(s["device"], s["device"]),
                f"{s['width']}x{s['height']}",
                len(s["spheres"]),
                _num(f["slope"]) if f else "–",
                _num(f["intercept"]) if f else "–",
                _r2(f["r2"]) if f else "–",
                _ms(s["first_frame_s"] * 1e3) if s["first_frame_s"] is not None else "–",
                _num(s["compile_s"]) if s["compile_s"] is not None else "–",
            ]
        )
    w(
        _table(
            [
                "device",
                "resolution",
                "frames",
                "slope (ms/sphere)",
                "intercept (ms)",
                "R²",
                "first frame, left out (ms)",
                "compile (s)",
            ],
            rows,
        ),
        "",
    )


def _section_tuning(w: _Writer, label: str, slug: str, records: list[dict]) -> None:
    w("### Tuning: CPU threads and GPU block shapes", "")
    cpu, gpu, portable = cpu_tuning(records), gpu_tuning(records), gpu_tuning(records, "wgpu")
    if not cpu and not gpu and not portable:
        w("Not measured: these results hold no `tuning` suite (`raybench bench --suite tuning`).", "")
        return
    w(
        "The same frame rendered with different ways of splitting the work. On the CPU the rows of the picture "
        "are shared among a number of threads (the thesis found twice the cores best, and one thread per row "
        "worse than a single thread). On the GPU every pixel is one thread, and threads are grouped in blocks "
        "of the shape shown (the thesis found the largest, 32x32, best). Lower is faster; the fastest bar is "
        "outlined.",
        "",
    )
    for device, _rows in (("cpu", cpu), ("cuda", gpu)):
        _, others = _largest_group(records, "tuning", device)
        if others:
            w(
                f"({DEVICE_NAMES[device]} tuning was also measured at {others} smaller size(s); the largest is shown.)",
                "",
            )
    if cpu or gpu:
        w.image(f"{slug}-tuning.png", _plot_tuning(label, cpu, gpu), f"{label}: tuning")
    if cpu:
        fastest = min(r["ms"] for r in cpu)
        w(
            _table(
                ["CPU setting", "threads", "median frame ms", "relative to fastest"],
                [[r["label"], r["threads"], _ms(r["ms"]), _x(r["ms"] / fastest)] for r in cpu],
            ),
            "",
        )
    else:
        w("CPU tuning: not measured.", "")
    if gpu:
        fastest = min(r["ms"] for r in gpu)
        timing = "kernel" if all(r["kernel_ms"] is not None for r in gpu) else "frame"
        w(
            _table(
                ["GPU block", "median frame ms", "median kernel ms", f"relative to fastest ({timing})"],
                [
                    [
                        r["label"],
                        _ms(r["frame_ms"]),
                        _ms(r["kernel_ms"]) if r["kernel_ms"] is not None else "–",
                        _x(r["ms"] / fastest),
                    ]
                    for r in gpu
                ],
            ),
            "",
        )
    else:
        w("GPU tuning: not measured.", "")
    if portable:
        fastest = min(r["ms"] for r in portable)
        timing = "kernel" if all(r["kernel_ms"] is not None for r in portable) else "frame"
        w(
            f"wgpu workgroups, on {_text(_adapter_name(records))}:",
            "",
            _table(
                ["wgpu workgroup", "median frame ms", "median kernel ms", f"relative to fastest ({timing})"],
                [
                    [
                        r["label"],
                        _ms(r["frame_ms"]),
                        _ms(r["kernel_ms"]) if r["kernel_ms"] is not None else "–",
                        _x(r["ms"] / fastest),
                    ]
                    for r in portable
                ],
            ),
            "",
        )


def _section_constant(w: _Writer, label: str, slug: str, records: list[dict]) -> None:
    w("### Sphere count: compile-time constant or runtime variable", "")
    rows = {d: constant_vs_runtime(records, d) for d in ("cuda", "cpu")}
    if not any(rows.values()):
        w(
            "Not measured: these results hold no `constant-vs-runtime` suite "
            "(`raybench bench --suite constant-vs-runtime`).",
            "",
        )
        return
    w(
        "The thesis's test 7 passed the sphere count to the shader at run time and blamed that for slower "
        "frames than a count fixed when the shader is compiled (which lets the compiler unroll the loop). "
        "Here the same kernel is compiled both ways and timed at each sphere count; a ratio above 1 means the "
        "runtime count is slower. On the GPU the kernel time is compared where it was measured.",
        "",
    )
    w.image(f"{slug}-constant.png", _plot_constant(label, rows), f"{label}: constant vs runtime sphere count")
    table = []
    for device, rs in rows.items():
        for r in rs:
            table.append(
                [
                    DEVICE_NAMES[device],
                    f"{r['width']}x{r['height']}",
                    r["spheres"],
                    r["timing"],
                    _ms(r["constant"]),
                    _ms(r["runtime"]),
                    _num(r["ratio"]),
                ]
            )
    w(
        _table(
            ["device", "resolution", "spheres", "timing", "constant (ms)", "runtime (ms)", "runtime / constant"], table
        ),
        "",
    )
    for device, rs in rows.items():
        if not rs:
            w(f"{DEVICE_NAMES[device]}: not measured.", "")


def _way(r: dict) -> str:
    return "BVH" if accel_of(r) == "bvh" else f"brute force, {kernel_of(r)} kernel"


def scaling_series(records: list[dict]) -> list[dict]:
    """The scaling suite: one series per (device, way of tracing, size), points
    sorted by sphere count; each point's median frame (and kernel) ms, rays/s
    and build s, or the reason it was skipped."""
    out: dict[tuple, dict] = {}
    for r in records:
        if r["suite"] != "scaling":
            continue
        key = (r["device"], _way(r), r["width"], r["height"])
        s = out.setdefault(
            key,
            {
                "device": r["device"],
                "way": _way(r),
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


def _plot_scaling(label: str, series: list[dict]) -> bytes:
    fig, (ax,) = _figure(width=8.0, height=5.2)
    for i, s in enumerate(series):
        done = [p for p in s["points"] if p["median"] is not None]
        if not done:
            continue
        style = "o-" if s["accel"] == "bvh" else "s--"
        name = f"{DEVICE_NAMES.get(s['device'], s['device'])}, {s['way']}, {s['width']}x{s['height']}"
        ax.plot(
            [p["spheres"] for p in done], [p["median"] for p in done], style, color=f"C{i}", markersize=4, label=name
        )
        if all(p["kernel"] for p in done):
            ax.plot([p["spheres"] for p in done], [p["kernel"] for p in done], ":", color=f"C{i}", linewidth=1.2)
        cut = [p for p in s["points"] if p["median"] is None]
        if cut:
            ax.axvline(cut[0]["spheres"], color=f"C{i}", linewidth=0.6, alpha=0.5)
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel("spheres in the scene")
    ax.set_ylabel("median frame time (ms); dotted: kernel only")
    ax.set_title(f"{label}: frame time against sphere count (thin line: brute force stopped)", fontsize=10)
    ax.legend(fontsize=7)
    return _png(fig)


def _section_scaling(w: _Writer, label: str, slug: str, records: list[dict]) -> None:
    series = scaling_series(records)
    if not series:
        return
    w(f"### {_md(label)}: scaling from 10 to 1,000,000 spheres", "")
    w(
        "Median frame time against the number of spheres (`random_spheres`, default camera), on log-log axes: "
        "brute force grows linearly (slope 1), the BVH about logarithmically. Brute force stops where its next "
        "frame, predicted linear in spheres from the last one measured, would pass the cap; those points are "
        "listed as skipped, not left out. BVH build time is measured apart from the frames.",
        "",
    )
    w.image(f"{slug}.png", _plot_scaling(label, series), f"{label}: frame time against sphere count")
    header = ["device", "way", "size", "spheres", "median frame ms", "kernel ms", "rays/s", "build ms"]
    rows = []
    for s in series:
        for p in s["points"]:
            base = [
                DEVICE_NAMES.get(s["device"], s["device"]),
                s["way"],
                f"{s['width']}x{s['height']}",
                f"{p['spheres']:,}",
            ]
            if p["median"] is None:
                rows.append(base + [f"skipped: {_md(_text(p['skipped']))}", "", "", ""])
                continue
            rows.append(
                base
                + [
                    _ms(p["median"]),
                    _ms(p["kernel"]) if p["kernel"] else "–",
                    f"{_num(p['rays_per_s'] / 1e6)} M" if p["rays_per_s"] else "–",
                    _ms(p["build_s"] * 1e3) if p["build_s"] is not None else "–",
                ]
            )
    w(_table(header, rows), "")


def _claims_table(machines: dict[str, list[dict]]) -> tuple[str, dict[str, list[dict]]]:
    judged = {label: verdicts(records) for label, records in machines.items()}
    header = ["#", "the thesis's claim", "what the thesis measured"] + [f"{label}" for label in machines]
    rows = []
    for i, (claim, thesis) in enumerate(CLAIMS):
        row = [i + 1, claim, thesis]
        for label in machines:
            v = judged[label][i]
            row.append(f"**{v['verdict']}**: {v['measured']}")
        rows.append(row)
    return _table(header, rows), judged


def write_report(paths: list, out_dir) -> Path:
    """Read the results files, write out_dir/report.md and its PNG plots
    (out_dir is created if needed), and return the path of report.md."""
    out_dir = Path(out_dir)
    if out_dir.exists() and not out_dir.is_dir():
        raise RaybenchError(f"{out_dir}: is a file, not a folder for the report")
    machines, notes = load(paths)
    # the scaling suite is no part of the thesis's claims: its own section per machine
    scaling: dict[str, list[dict]] = {}
    for records in machines.values():
        for r in records:
            if r["suite"] == "scaling":
                scaling.setdefault(r["run"]["label"], []).append(r)
    machines = {k: v for k, v in ((k, [r for r in v if r["suite"] != "scaling"]) for k, v in machines.items()) if v}
    try:
        out_dir.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise RaybenchError(f"{out_dir}: cannot create the report folder ({exc.strerror or exc})") from None

    w = _Writer(out_dir)
    names = ", ".join(
        dict.fromkeys([records[0]["run"]["label"] for records in machines.values() if records] + list(scaling))
    )
    w(f"# raybench: the 2010 GPU ray-tracing thesis, measured again on {names}", "")
    w(
        "Persson and Udd (2010) rendered spheres with one brute-force ray tracer (one primary ray per pixel, "
        f"tested against every sphere) on an {THESIS_CPU} and on a {THESIS_GPU} with a DirectX 11 compute "
        "shader. raybench runs the same algorithm, written once, on this machine's CPU (Numba) and GPU "
        "(numba-cuda), repeats the thesis's tests, and checks each of its claims below. Times are medians "
        "over many frames; every number comes from the results files listed at the end.",
        "",
    )
    w("## Machines", "")
    for label, records in machines.items():
        w(*_machine_lines(label, records), "")
    w("## The thesis's claims", "")
    table, judged = _claims_table(machines)
    w(table, "", "How the verdicts are decided:", "")
    w(*[f"- {rule}" for rule in RULES], "")
    taken: set = set()
    for label, records in machines.items():
        slug = _slug(label, taken)
        w(f"## {_md(label)}", "")
        w(*_machine_lines(label, records), "")
        for section in (_section_thesis, _section_speedup, _section_test7, _section_tuning, _section_constant):
            section(w, label, slug, records)
    if scaling:
        w("## Beyond the thesis: scaling with a BVH", "")
        for label, records in scaling.items():
            _section_scaling(w, label, _slug(f"{label}-scaling", taken), records)
    w("## Sources", "")
    w(*[f"- `{Path(p)}`" for p in paths], "")
    if notes:
        w("## Notes", "")
        w(*[f"- {_md(n)}" for n in notes], "")
    report = out_dir / "report.md"
    write_atomic(report, "\n".join(w.lines).encode("utf-8"))
    return report
