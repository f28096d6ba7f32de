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


def _counts(record: dict, device: str) -> bool:
    options = record.get("options") or {}
    seed = ((record["run"].get("settings") or {}).get("seed")) or 0
    return (
        record["suite"] == "thesis"
        and record["device"] == device
        and "skipped" not in record
        and (record["width"], record["height"]) == SIZE
        and record["spheres"] in SPHERES
        and options.get("accel", "none") == "none"
        # records from before the fast kernel carry none, and were the simple one's
        and options.get("kernel", "simple") == KERNELS[device]
        and seed == 0
    )


def score(records: list[dict], device: str) -> float | None:
    """The headline of device from one machine's records, or None where a point is missing."""
    found = {r["spheres"]: r["frame_ms"]["median"] for r in records if _counts(r, device)}
    if set(found) != set(SPHERES):
        return None
    rates = [SIZE[0] * SIZE[1] / (found[n] / 1e3) / 1e6 for n in SPHERES]
    return math.exp(sum(map(math.log, rates)) / len(rates))


# The headline's interval: a moving-block bootstrap over each point's kept frames (in the order
# they were timed), so that a stretch of slow frames, a neighbour's burst of work, moves the
# resampled medians together as it moved the run. Blocks of a tenth of the frames; fixed seed.
ROUNDS = 2000
SPREAD_WARN = 0.10  # an interval wider than this either side of the headline is too loose to quote alone
# The interval resamples one run's frames, so a load or a clock that held through a whole point
# moves every frame and its resamples together: two runs on a shared machine fell outside each
# other's (docs/thesis.md#the-headlines-interval-one-runs-frames). It is stated as what it is,
# not widened by a guessed between-run term: one run holds no measure of the next.
WITHIN_RUN = (
    "each interval is over its own run's frames only: a load or a clock that held through a whole point "
    "moves all its frames together, and another run can fall outside it"
)


def _block_medians(samples: np.ndarray, rng: np.random.Generator, rounds: int) -> np.ndarray:
    n = samples.size
    block = max(1, n // 10)
    starts = rng.integers(0, n - block + 1, size=(rounds, -(-n // block)))
    picked = (starts[:, :, None] + np.arange(block)).reshape(rounds, -1)[:, :n]
    return np.median(samples[picked], axis=1)


def interval(records: list[dict], device: str, rounds: int = ROUNDS) -> tuple[float, float] | None:
    """The 95% interval of device's headline from one machine's records: the frames of each of
    its three points resampled in blocks, the geometric mean taken each round. None where a
    point is missing or kept too few frames (records from before samples_ms). It is the spread
    within one run (WITHIN_RUN): what stayed the same through a point's frames, a neighbour's
    load or the clock, it cannot see."""
    found = {r["spheres"]: r.get("samples_ms") or [] for r in records if _counts(r, device)}
    if set(found) != set(SPHERES) or any(len(s) < 5 for s in found.values()):
        return None
    rng = np.random.default_rng(0)
    logs = sum(
        np.log(SIZE[0] * SIZE[1] / (_block_medians(np.asarray(found[n], dtype=np.float64), rng, rounds) / 1e3) / 1e6)
        for n in SPHERES
    )
    low, high = np.percentile(np.exp(logs / len(SPHERES)), [2.5, 97.5])
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
    loose, spans = [], 0
    width = max([14] + [len(r["label"]) for r in table if r["reference"]])  # the figures in one column
    for r in mine:
        extra = ""
        if r["device"] != "cpu" and r["cpu_ratio"]:
            extra = f"  ({r['cpu_ratio']:.3g}x this machine's CPU)"
        span = interval([x for x in records if x["run"]["label"] == r["label"]], r["device"])
        if span is not None:
            spans += 1
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
        out.append(f"  {WITHIN_RUN} (docs/thesis.md#the-headlines-interval-one-runs-frames)")
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
