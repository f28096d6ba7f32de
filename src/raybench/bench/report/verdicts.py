"""The thesis's six claims judged on one column's records. The thresholds are
the module constants below; RULES states them in words, and the report prints it."""

from __future__ import annotations

import math
import statistics

from .numbers import fmt_ms, fmt_num, fmt_r2, fmt_x
from .series import (
    DEVICE_NAMES,
    constant_vs_runtime,
    cpu_tuning,
    gpu_tuning,
    machine_of,
    secondary_leads,
    speedups,
    test7_series,
    theoretical_ratio,
    thesis_series,
)

HOLDS, FAILS, NOT_MEASURED = "holds", "does not hold", "not measured"

THESIS_SPEEDUP = (58.0, 60.0)  # "between 58 and 60 times faster"
THESIS_CPU = "Intel Core i5 750 (4 cores, 2.67 GHz)"
THESIS_GPU = "Radeon HD 5770 (800 cores, 850 MHz)"
THESIS_RATIO = (800 * 0.85) / (4 * 2.67)  # the thesis's "about 64": cores x GHz, no SIMD
R2_MIN = 0.98  # claim 2: every series at least this linear
RATIO_BAND = (2 / 3, 3 / 2)  # claim 3: measured / theoretical speedup inside this band
NEAR_FASTEST = 1.05  # claims 4, 5: "within 5% of the fastest"
RUNTIME_SLOWER = 1.02  # claim 6: runtime / constant above this at every count

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
        f"min {fmt_x(low['speedup'])} ({_where(low)}), median {fmt_x(statistics.median(values))}, "
        f"max {fmt_x(max(values))} over {len(sp)} matched points (CPU median frame time / GPU's, point by point)"
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
    text = f"lowest R² {fmt_r2(r2)} ({name}) over {len(fits)} series"
    if bad:
        text += f"; {len(bad)} below {R2_MIN}"
    return (FAILS if bad else HOLDS), text, {"min_r2": r2, "series": name, "n": len(fits), "below": bad}


def _claim3(records):
    sp = speedups(records)
    ratio = theoretical_ratio(machine_of(records))
    if not sp:
        return NOT_MEASURED, "needs tests 1-6 on both CPU and GPU", {"theoretical": ratio}
    median = statistics.median(p["speedup"] for p in sp)
    if ratio is None:
        return (
            NOT_MEASURED,
            f"median speedup {fmt_x(median)}; the machine description lacks a CPU or GPU FP32 rate",
            {"median": median, "theoretical": None},
        )
    share = median / ratio
    ok = RATIO_BAND[0] <= share <= RATIO_BAND[1]
    text = f"median speedup {fmt_x(median)} against theoretical {fmt_x(ratio)}: {fmt_num(share)} of it"
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
        text = f"32x32 is the fastest of {len(shapes)} shapes ({fmt_ms(big['ms'])} ms {timing})"
    else:
        text = f"fastest {fastest['label']} ({fmt_ms(fastest['ms'])} ms {timing}); 32x32 takes {fmt_num(rel)}x as long"
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
            else (f"takes {fmt_num(rel)}x the fastest ({fastest['label']}, {fastest['threads']} threads)")
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
            f"one per row ({row['threads']} threads) takes {fmt_num(rel)}x the time of 1 thread: "
            f"{HOLDS if ok else FAILS}"
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
            + ", ".join(f"{fmt_num(r['ratio'])} ({r['spheres']})" for r in rows)
            + " at (spheres)"
        )

    info = f"; CPU (information): {listing(cpu)}" if cpu else ""
    values = {"gpu": [r["ratio"] for r in gpu], "cpu": [r["ratio"] for r in cpu]}
    if not gpu:
        return NOT_MEASURED, "needs constant-vs-runtime on the GPU" + info, values
    ok = all(r["ratio"] > RUNTIME_SLOWER for r in gpu)
    return (HOLDS if ok else FAILS), f"GPU: {listing(gpu)}{info}", values


# --- beyond the thesis: secondary rays (docs/notes/whitted.md) -----------------------------

SECONDARY_QUESTION = "Does the GPU's lead over the CPU hold for secondary rays?"
# Fixed before any data was taken: the GPU keeps at least this share of its
# lead on primary rays, and is still faster.
SECONDARY_KEPT_MIN = 0.5
SECONDARY_RULE = (
    "Fixed before any data. For every point of the secondary suite (a way of tracing, size and sphere "
    "count) that both the CPU and the GPU (cuda) measured with both shadings: the GPU's lead on secondary "
    "rays is GPU rays/s / CPU rays/s of the Whitted frames (every ray cast counted, by the kernels; "
    "median frame times, whole frames), its lead on primary rays is the same ratio for the point's "
    "thesis-shading twin (the same spheres, size and way, one ray a pixel; the suite times it right "
    "before the Whitted frame, in the same run), and "
    "the share kept is the first divided by the second. A way of tracing (BVH, brute force) holds if the "
    f"median share kept over its points is at least {SECONDARY_KEPT_MIN} and the median lead on secondary "
    "rays is above 1 (the GPU still faster); a way with no such point is left out. The answer holds if "
    "every way left holds, does not hold if any does not, and cannot be decided where no way has a point "
    "measured on both devices (only one device ran). wgpu's leads are shown for information and decide "
    "nothing."
)


def secondary_verdict(records: list[dict], gpu: str = "cuda") -> dict:
    """The question SECONDARY_QUESTION judged under SECONDARY_RULE on one
    machine's records: verdict (HOLDS, FAILS or NOT_MEASURED), measured (one
    line), ways ({way: {"verdict", "kept", "lead", "primary", "n"}}) and the
    matched points (secondary_leads)."""
    leads = secondary_leads(records, gpu)
    name = "the GPU" if gpu == "cuda" else DEVICE_NAMES.get(gpu, gpu)
    if not leads:
        who = "the GPU (cuda)" if gpu == "cuda" else name
        return {
            "verdict": NOT_MEASURED,
            "measured": f"cannot be decided: needs the secondary suite on both the CPU and {who} "
            "at the same points, each with its thesis-shading twin",
            "ways": {},
            "points": [],
        }
    ways, parts = {}, []
    for way in dict.fromkeys(p["way"] for p in leads):
        mine = [p for p in leads if p["way"] == way]
        kept = statistics.median(p["kept"] for p in mine)
        lead = statistics.median(p["secondary"] for p in mine)
        primary = statistics.median(p["primary"] for p in mine)
        # kept is a ratio of ratios of medians: exactly at the threshold, its
        # float rounding can land a few ulps under it, which no rule means
        ok = kept >= SECONDARY_KEPT_MIN * (1 - 1e-9) and lead > 1
        ways[way] = {"verdict": HOLDS if ok else FAILS, "kept": kept, "lead": lead, "primary": primary, "n": len(mine)}
        parts.append(
            f"{way}: {name} leads by {fmt_x(lead)} on secondary rays against {fmt_x(primary)} on primary "
            f"rays (medians), keeping {fmt_num(kept)} of its lead over {len(mine)} point{'s' * (len(mine) != 1)}: "
            f"{HOLDS if ok else FAILS}"
        )
    verdict = HOLDS if all(w["verdict"] == HOLDS for w in ways.values()) else FAILS
    return {"verdict": verdict, "measured": "; ".join(parts), "ways": ways, "points": leads}


def with_reference_gpus(machines: dict[str, list[dict]], references: list[dict]) -> list[dict]:
    """The claims that need a GPU (1, 3, 4 and 6), for each machine here that
    has none, judged with each reference machine's GPU measured the same way
    (accel and kernel): its CPU's records beside that GPU's, as if on one
    machine, the GPU always named as another's. One dict a pair: label, ref
    (the reference's label), gpu (its name), commit, date, judged (verdicts())."""
    from .. import headline
    from .records import accel_of, kernel_of

    by_ref: dict[str, list[dict]] = {}
    for r in references:
        by_ref.setdefault(r["run"]["label"], []).append(r)
    out = []
    for label, records in machines.items():
        cpu = [r for r in records if r["device"] == "cpu" and r["suite"] == "thesis"]
        if not cpu or any(r["device"] == "cuda" for r in records):
            continue
        way = (accel_of(cpu[0]), kernel_of(cpu[0]))
        for ref, ref_records in by_ref.items():
            gpu = [r for r in ref_records if r["device"] == "cuda" and (accel_of(r), kernel_of(r)) == way]
            if not any(r["suite"] == "thesis" for r in gpu):
                continue
            machine = {**cpu[0]["run"]["machine"], "gpus": gpu[0]["run"]["machine"].get("gpus") or []}
            paired = [{**r, "run": {**r["run"], "machine": machine}} for r in records + gpu]
            out.append(
                {
                    "label": label,
                    "ref": ref,
                    "gpu": headline.device_name(gpu[0]["run"]["machine"], "cuda"),
                    "commit": gpu[0]["run"].get("git_commit") or "not recorded",
                    "date": gpu[0]["run"].get("date") or "date not recorded",
                    "judged": [v for v in verdicts(paired) if v["number"] in (1, 3, 4, 6)],
                }
            )
    return out
