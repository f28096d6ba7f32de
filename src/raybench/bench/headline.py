"""The headline: one number a device, defined once, versioned, and placed
against raybench's reference machines (raybench.references).

Version 1: million primary rays a second by brute force (every ray tested
against every sphere, the thesis's own algorithm; the fast kernel on cpu and
cuda, the simple one on wgpu, its only one), on the thesis's scenes
(random_spheres, seed 0) at 800x600 with 100, 500 and 1000 spheres: the
geometric mean over those three points of width x height / median whole-frame
time (on a GPU, the frame's copy to the host included). Every `raybench bench`
of the thesis suite measures those points, --quick included. A change to any
of that is a new VERSION, never the same number redefined.
"""

from __future__ import annotations

import math

import numpy as np

VERSION = 1
SIZE = (800, 600)
SPHERES = (100, 500, 1000)
KERNELS = {"cpu": "fast", "cuda": "fast", "wgpu": "simple"}
DEVICES = ("cpu", "cuda", "wgpu")
DEFINITION = (
    f"headline v{VERSION}: million rays a second, brute force (every ray against every sphere), "
    f"the thesis's scenes at {SIZE[0]}x{SIZE[1]} with {', '.join(map(str, SPHERES))} spheres, geometric mean"
)


def counts_point(suite: str, device: str, size: tuple, spheres: int, options: dict) -> bool:
    """Whether a point of a suite is one of the headline's on its device."""
    return (
        suite == "thesis"
        and device in KERNELS
        and tuple(size) == SIZE
        and spheres in SPHERES
        and options.get("accel", "none") == "none"
        # records from before the fast kernel carry none, and were the simple one's
        and options.get("kernel", "simple") == KERNELS[device]
    )


def _counts(record: dict, device: str) -> bool:
    seed = ((record["run"].get("settings") or {}).get("seed")) or 0
    return (
        record["device"] == device
        and "skipped" not in record
        and seed == 0
        and counts_point(
            record["suite"], device, (record["width"], record["height"]), record["spheres"], record.get("options") or {}
        )
    )


def _passes(record: dict) -> list[list[float]]:
    """A headline point's kept frame times, pass by pass: its own, then each of its repeats'
    (bench times the headline's points again later in the run: suites.HEADLINE_REPEATS)."""
    return [list(record.get("samples_ms") or [])] + [list(r.get("samples_ms") or []) for r in record.get("repeats", ())]


def _median_ms(record: dict) -> float:
    """A point's median frame time: over every pass's frames where it was timed again."""
    if record.get("repeats"):
        return float(np.median(np.concatenate([np.asarray(p, dtype=np.float64) for p in _passes(record)])))
    return record["frame_ms"]["median"]


def _rate(ms):
    return SIZE[0] * SIZE[1] / (np.asarray(ms, dtype=np.float64) / 1e3) / 1e6


def score(records: list[dict], device: str) -> float | None:
    """The headline of device from one machine's records, or None where a point is missing."""
    found = {r["spheres"]: _median_ms(r) for r in records if _counts(r, device)}
    if set(found) != set(SPHERES):
        return None
    rates = [float(_rate(found[n])) for n in SPHERES]
    return math.exp(sum(map(math.log, rates)) / len(rates))


# The headline's interval, from two sources, the wider taken:
# - within the run: a moving-block bootstrap over each point's kept frames (in the order they
#   were timed), so that a stretch of slow frames moves the resampled medians together as it
#   moved the run. Blocks of a tenth of the frames; fixed seed.
# - between passes: bench times the headline's points again, later in the run, afresh
#   (suites.HEADLINE_REPEATS), and the passes' headlines give a Student's t interval. A drift
#   that held through one pass's frames, the clock or a neighbour over minutes, moves one pass
#   and not the others; frames alone cannot see it (docs/thesis.md#the-headlines-interval).
ROUNDS = 2000
SPREAD_WARN = 0.10  # an interval wider than this either side of the headline is too loose to quote alone
# Student's t at 97.5% by degrees of freedom (passes less one): numpy has no t quantile
T_975 = {1: 12.706, 2: 4.303, 3: 3.182, 4: 2.776, 5: 2.571, 6: 2.447, 7: 2.365, 8: 2.306}
PAGE = "docs/thesis.md#the-headlines-interval"
SPANS = (
    "each interval spans its run's passes over the headline's points (the first, and the repeats "
    "later in the run): a load that held through the whole run moves them all, and another run can fall outside it"
)
SPANS_FRAMES = (
    "this interval is over one pass's frames only (its records have no repeats): a load or a clock that held "
    "through a whole point moves all its frames together, and another run can fall outside it"
)


def _block_medians(samples: np.ndarray, rng: np.random.Generator, rounds: int) -> np.ndarray:
    n = samples.size
    block = max(1, n // 10)
    starts = rng.integers(0, n - block + 1, size=(rounds, -(-n // block)))
    picked = (starts[:, :, None] + np.arange(block)).reshape(rounds, -1)[:, :n]
    return np.median(samples[picked], axis=1)


def _headline_records(records: list[dict], device: str) -> dict[int, list[list[float]]] | None:
    found = {r["spheres"]: _passes(r) for r in records if _counts(r, device)}
    if set(found) != set(SPHERES) or any(len(p[0]) < 5 for p in found.values()):
        return None
    return found


def passes(records: list[dict], device: str) -> int:
    """How many passes over the headline's points the records hold whole (each point timed in
    each): 1 for records without repeats, 0 where there is no interval at all."""
    found = _headline_records(records, device)
    return 0 if found is None else len(_whole(found))


def _whole(found: dict[int, list[list[float]]]) -> list[int]:
    """The passes in which every headline point kept enough frames (five) to count."""
    return [k for k in range(min(map(len, found.values()))) if all(len(ps[k]) >= 5 for ps in found.values())]


def interval(records: list[dict], device: str, rounds: int = ROUNDS) -> tuple[float, float] | None:
    """The 95% interval of device's headline from one machine's records: the wider of the
    bootstrap over each point's frames (every pass's, pooled) and Student's t over the passes'
    headlines where the points were timed again. None where a point is missing or kept too
    few frames (records from before samples_ms)."""
    found = _headline_records(records, device)
    if found is None:
        return None
    rng = np.random.default_rng(0)
    pooled = {n: np.concatenate([np.asarray(p, dtype=np.float64) for p in ps]) for n, ps in found.items()}
    logs = sum(np.log(_rate(_block_medians(pooled[n], rng, rounds))) for n in SPHERES)
    low, high = np.percentile(np.exp(logs / len(SPHERES)), [2.5, 97.5])
    whole = _whole(found)
    if len(whole) >= 2:
        each = np.array([sum(np.log(_rate(np.median(found[n][k]))) for n in SPHERES) / len(SPHERES) for k in whole])
        half = T_975[min(len(whole) - 1, max(T_975))] * each.std(ddof=1) / math.sqrt(len(whole))
        low, high = min(low, math.exp(each.mean() - half)), max(high, math.exp(each.mean() + half))
    return float(low), float(high)


def scores(records: list[dict]) -> dict[str, dict[str, float]]:
    """{machine label: {device: headline}} of every device measured at the headline's workload."""
    by: dict[str, list[dict]] = {}
    for r in records:
        by.setdefault(r["run"]["label"], []).append(r)
    out = {}
    for label, rs in by.items():
        got = {d: s for d in DEVICES if (s := score(rs, d)) is not None}
        if got:
            out[label] = got
    return out


def device_name(machine: dict, device: str) -> str:
    """A device as the reader knows it: a GPU's name, or the CPU's model and cores."""
    if device == "cpu":
        cpu = machine.get("cpu") or {}
        cores = cpu.get("physical_cores")
        return f"{cpu.get('model') or 'CPU'}" + (f", {cores} cores" if cores else "")
    gpus = machine.get("gpus") or []
    if device == "cuda" and gpus:
        return str(gpus[0].get("name") or "GPU")
    return {"cuda": "GPU (cuda)", "wgpu": "GPU (wgpu)"}.get(device, device)


def _fmt(x: float) -> str:
    return f"{x:,.0f}" if x >= 100 else f"{x:.3g}"


def rows(records: list[dict], references: list[dict]) -> list[dict]:
    """The headline table: this run's machines, then each reference machine's
    devices, each with its ratio to this run's CPU (the first machine's) and,
    where this run has a GPU, to it. Each row: label, device, name, value,
    reference (bool), commit, cpu_ratio."""
    own, refs = scores(records), scores(references)
    base = next((s["cpu"] for s in own.values() if "cpu" in s), None)
    out = []
    for table, reference in ((own, False), (refs, True)):
        for label, devices in table.items():
            source = references if reference else records
            for device, value in devices.items():
                # the machine and commit of the records counted: one label may hold runs of other
                # commits and settings (the 2-core EPYC's simple-kernel run beside its fast one)
                counted = next(r["run"] for r in source if r["run"]["label"] == label and _counts(r, device))
                machine, commit = counted.get("machine") or {}, counted.get("git_commit")
                out.append(
                    {
                        "label": label,
                        "device": device,
                        "name": device_name(machine, device),
                        "value": value,
                        "reference": reference,
                        "commit": commit,
                        "cpu_ratio": value / base if base else None,
                    }
                )
    return out


def unscored(references: list[dict]) -> list[str]:
    """Reference machines with thesis records but no headline, each with why: a reader who
    looks for a machine in the table is told why it is not there."""
    scored = scores(references)
    out = []
    for label in dict.fromkeys(r["run"]["label"] for r in references if r["suite"] == "thesis"):
        if label in scored:
            continue
        mine = [r for r in references if r["run"]["label"] == label and r["suite"] == "thesis"]
        kernels = sorted({(r.get("options") or {}).get("kernel", "simple") for r in mine})
        out.append(
            f"{label}: no headline v{VERSION}: its thesis records are the {' and '.join(kernels)} kernel's, "
            f"and the headline counts brute force by the fast kernel at {SIZE[0]}x{SIZE[1]}"
        )
    return out


def summary(records: list[dict], references: list[dict]) -> list[str]:
    """What `raybench bench` prints at its end: this machine's headline per
    device, the GPU over the CPU here, and where each stands against the
    references, those labelled as other machines."""
    table = rows(records, references)
    mine = [r for r in table if not r["reference"]]
    if not mine:
        return [f"{DEFINITION}: not measured in this run (it needs the thesis suite)"]
    out = [f"{DEFINITION}:"]
    loose, spans, whole = [], 0, True
    width = max([14] + [len(r["label"]) for r in table if r["reference"]])  # the figures in one column
    for r in mine:
        extra = ""
        if r["device"] != "cpu" and r["cpu_ratio"]:
            extra = f"  ({r['cpu_ratio']:.3g}x this machine's CPU)"
        span = interval([x for x in records if x["run"]["label"] == r["label"]], r["device"])
        if span is not None:
            spans += 1
            whole &= passes([x for x in records if x["run"]["label"] == r["label"]], r["device"]) >= 2
            extra = f"  (95% interval {_fmt(span[0])} to {_fmt(span[1])}){extra}"
            if span[1] - span[0] > 2 * SPREAD_WARN * r["value"]:
                loose.append(r["name"])
        else:
            extra = f"  (too few frames for an interval: a longer --duration gives one){extra}"
        out.append(f"  {'this machine':<{width}} {r['name']:<40} {_fmt(r['value']):>9}{extra}")
    if loose:
        out.append(
            f"  warning: the interval of {', '.join(loose)} is wider than +-{SPREAD_WARN:.0%}: its frames varied "
            "(another program's load, a clock that changed); run again on a quiet machine to quote it"
        )
    if spans:
        out.append(f"  {SPANS if whole else SPANS_FRAMES} ({PAGE})")
    others = [r for r in table if r["reference"]]
    if others:
        out.append("  reference machines (measured elsewhere, shipped with raybench; not this machine):")
        for r in others:
            ratio = f"  ({r['cpu_ratio']:.3g}x this CPU)" if r["cpu_ratio"] else ""
            out.append(f"  {r['label']:<{width}} {r['name']:<40} {_fmt(r['value']):>9}{ratio}")
        out += [f"  {line}" for line in unscored(references)]
    has_gpu = any(r["device"] != "cpu" for r in mine)
    base = next((r for r in mine if r["device"] == "cpu"), None)
    gpus = [r for r in others if r["device"] == "cuda"]
    if not has_gpu and base is not None and gpus:
        best = ", ".join(f"{r['name']} {r['cpu_ratio']:.3g}x" for r in gpus)
        out.append(
            f"  no GPU measured here: on the reference machines a GPU traces {best} the rays a second "
            "of this CPU (other machines' GPUs against this CPU)"
        )
    return out
