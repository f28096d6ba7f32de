"""Two runs compared point by point: for each point measured in both, the
change in its median frame time with a confidence interval, and a verdict:
faster, slower, or within noise.

The interval is a bootstrap over frames where both records carry their
frames (samples_ms, recorded since results had them): each run's frames are
drawn again with replacement, BOOTSTRAP times, and the ratio of the two
medians taken each time; its 2.5th and 97.5th percentiles bound the change.
A test-7 ramp pairs its frames by sphere count instead, and the bootstrap
draws the pairs. Records from before samples_ms carry only a summary; their
interval is the normal approximation of a median's error from the summary
(p5 to p95 spans 3.29 standard deviations of a normal distribution; a
median's standard error is 1.2533 sigma / sqrt(frames)), and the table says so.

A change is called faster or slower only when its interval excludes no
change AND the change is larger than the noise floor (asv's rule: both
significant and large enough); a re-run of one commit on one machine
differs by a few percent that no interval over frames captures (the
machine's state between runs), which the floor absorbs.

Points are matched by what was measured: suite, test, quantity, device,
size, spheres and options. Machines may differ (that is a comparison of
machines); a point of one run with no match in the other is listed, with
the fields in which its nearest point of the other run differs ("not
comparable").
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass, field

import numpy as np

from ..errors import RaybenchError

BOOTSTRAP = 2000
CONFIDENCE = 0.95
NOISE_PCT = 5.0
# z of the two-sided interval, and a normal distribution's p5 to p95 in sigmas
_Z = 1.959963984540054
_P5_P95_SIGMAS = 3.289707253902945

FASTER, SLOWER, NOISE = "faster", "slower", "within noise"
IDENTITY = ("suite", "test", "quantity", "device", "width", "height", "spheres", "options")


def identity(record: dict) -> tuple:
    """What a record measured: two records with the same identity are the same point."""
    return tuple(json.dumps(record.get(k), sort_keys=True) if k == "options" else record.get(k) for k in IDENTITY)


def describe(record: dict) -> str:
    """A point in a few words: 'thesis cpu 1680x1050 1000 spheres (accel bvh, threads 2)'."""
    what = f"parts {record['quantity']}" if record["suite"] == "parts" else record["suite"]
    if record.get("test") is not None:
        what += f" test {record['test']}"
    size = f" {record['width']}x{record['height']}" if "width" in record and "height" in record else ""
    spheres = f" {record['spheres']} spheres" if "spheres" in record else ""
    opts = ", ".join(
        f"{k} {'x'.join(map(str, v)) if isinstance(v, list) else v}" for k, v in (record.get("options") or {}).items()
    )
    return f"{what} {record['device']}{size}{spheres}" + (f" ({opts})" if opts else "")


@dataclass
class Change:
    """One point measured in both runs. ratio: new median over old (above 1:
    slower); low, high: its interval; method: "bootstrap", "paired" or "summary"."""

    point: str
    old_ms: float
    new_ms: float
    ratio: float
    low: float
    high: float
    method: str
    verdict: str = NOISE

    @property
    def change_pct(self) -> float:
        return (self.ratio - 1.0) * 100.0


@dataclass
class Comparison:
    changes: list[Change] = field(default_factory=list)
    # points of one run with no match in the other: (run, point, why)
    unmatched: list[tuple[str, str, str]] = field(default_factory=list)
    machines: tuple[str, str] = ("", "")
    notes: list[str] = field(default_factory=list)

    def slower(self, pct: float) -> list[Change]:
        """Points judged slower by at least pct percent."""
        return [c for c in self.changes if c.verdict == SLOWER and c.change_pct >= pct]


def _times(record: dict) -> dict:
    return record["time_ms"] if record["suite"] == "parts" else record["frame_ms"]


def _frames(record: dict) -> int:
    return int(record.get("samples") if record["suite"] == "parts" else record.get("frames") or 0)


def _summary_interval(old: dict, new: dict) -> tuple[float, float] | None:
    """The interval of log(new median / old median) from the summaries alone
    (the normal approximation above), or None where a side has under 2 frames."""
    var = 0.0
    for record in (old, new):
        n, t = _frames(record), _times(record)
        if n < 2:
            return None
        sigma = (t["p95"] - t["p5"]) / _P5_P95_SIGMAS
        var += (1.2533141373155 * sigma / math.sqrt(n) / t["median"]) ** 2
    return -_Z * math.sqrt(var), _Z * math.sqrt(var)


def bootstrap_ratio(old, new, rng: np.random.Generator, rounds: int = BOOTSTRAP) -> tuple[float, float, float]:
    """The ratio of new's median to old's, and its bootstrap interval at CONFIDENCE."""
    old = np.asarray(old, dtype=np.float64)
    new = np.asarray(new, dtype=np.float64)
    ratio = float(np.median(new) / np.median(old))
    draws_old = np.median(old[rng.integers(0, old.size, (rounds, old.size))], axis=1)
    draws_new = np.median(new[rng.integers(0, new.size, (rounds, new.size))], axis=1)
    tail = (1 - CONFIDENCE) / 2 * 100
    low, high = np.percentile(draws_new / draws_old, [tail, 100 - tail])
    return ratio, float(low), float(high)


def paired_ratio(old, new, rng: np.random.Generator, rounds: int = BOOTSTRAP) -> tuple[float, float, float]:
    """The geometric mean of new/old over paired frames, and its bootstrap interval."""
    logs = np.log(np.asarray(new, dtype=np.float64) / np.asarray(old, dtype=np.float64))
    draws = logs[rng.integers(0, logs.size, (rounds, logs.size))].mean(axis=1)
    tail = (1 - CONFIDENCE) / 2 * 100
    low, high = np.percentile(draws, [tail, 100 - tail])
    return float(np.exp(logs.mean())), float(np.exp(low)), float(np.exp(high))


def judge(ratio: float, low: float, high: float, noise_pct: float) -> str:
    """faster or slower only if the interval excludes 1 and the change passes the floor
    (symmetric in log: 5% slower is 1.05x the time, 5% faster 1/1.05x)."""
    floor = math.log1p(noise_pct / 100)
    if low > 1 and math.log(ratio) > floor:
        return SLOWER
    if high < 1 and -math.log(ratio) > floor:
        return FASTER
    return NOISE


def change(old: dict, new: dict, rng: np.random.Generator, noise_pct: float = NOISE_PCT) -> Change:
    """The change of one point from old's record to new's."""
    old_ms, new_ms = _times(old)["median"], _times(new)["median"]
    if old["suite"] == "test7" and old["series"]["spheres"] == new["series"]["spheres"]:
        ratio, low, high = paired_ratio(old["series"]["frame_ms"], new["series"]["frame_ms"], rng)
        method = "paired"
        old_ms, new_ms = sum(old["series"]["frame_ms"]), sum(new["series"]["frame_ms"])
    elif len(old.get("samples_ms") or ()) >= 2 and len(new.get("samples_ms") or ()) >= 2:
        ratio, low, high = bootstrap_ratio(old["samples_ms"], new["samples_ms"], rng)
        method = "bootstrap"
    else:
        ratio = new_ms / old_ms
        spread = _summary_interval(old, new)
        # one frame a side: no interval at all, so nothing can be called
        low, high = (ratio * math.exp(spread[0]), ratio * math.exp(spread[1])) if spread else (0.0, math.inf)
        method = "summary"
    return Change(describe(new), old_ms, new_ms, ratio, low, high, method, judge(ratio, low, high, noise_pct))


def _measured(records: list[dict]) -> dict[str, dict[tuple, dict]]:
    """Records by machine label, then by identity; the later record of a point measured twice wins."""
    out: dict[str, dict[tuple, dict]] = {}
    for r in records:
        out.setdefault(r["run"]["label"], {})[identity(r)] = r
    return out


def _option_changes(a: dict, b: dict) -> list[str]:
    oa, ob = a.get("options") or {}, b.get("options") or {}
    return [f"{k} {oa.get(k, '-')} -> {ob.get(k, '-')}" for k in sorted(set(oa) | set(ob)) if oa.get(k) != ob.get(k)]


def _unmatched(side: str, record: dict, others: list[dict]) -> tuple[str, str, str]:
    """Why a point has no match: skipped on its side, measured with other
    options in the other run (the same workload: not comparable), or absent there."""
    if "skipped" in record:
        return side, describe(record), f"not measured in {side} ({record['skipped']})"
    same = [k for k in IDENTITY if k != "options"]
    kin = [o for o in others if [o.get(k) for k in same] == [record.get(k) for k in same]]
    if not kin:
        return side, describe(record), f"only in {side}"
    nearest = min(kin, key=lambda o: len(_option_changes(record, o)))
    old, new = (record, nearest) if side == "OLD" else (nearest, record)
    return (
        side,
        describe(record),
        "not comparable: the other run measured it with other options (" + ", ".join(_option_changes(old, new)) + ")",
    )


def compare(old: list[dict], new: list[dict], noise_pct: float = NOISE_PCT, seed: int = 0) -> Comparison:
    """old's and new's records (results.read), compared point by point.
    A run holding several machines (bench --scheduler) is matched machine by
    machine, by label; two runs of one machine each are compared whatever
    their labels (two machines, or one machine twice)."""
    if not 0 <= noise_pct <= 1000 or math.isnan(noise_pct):
        raise RaybenchError(f"--noise: must be from 0 to 1000 percent, got {noise_pct:g}")
    rng = np.random.default_rng(seed)
    sides = _measured(old), _measured(new)
    out = Comparison()
    if len(sides[0]) == 1 and len(sides[1]) == 1:
        pairs = [(next(iter(sides[0])), next(iter(sides[1])))]
    else:
        pairs = [(label, label) for label in sides[0] if label in sides[1]]
        for n, side in enumerate(sides):
            other = sides[1 - n]
            for label in side:
                if label not in other:
                    out.notes.append(f"machine {label} is only in {('OLD', 'NEW')[n]}; its points are not compared")
    out.machines = (", ".join(p[0] for p in pairs), ", ".join(p[1] for p in pairs))
    for old_label, new_label in pairs:
        a, b = sides[0][old_label], sides[1][new_label]
        prefix = f"{old_label}: " if len(pairs) > 1 else ""
        for key, record in a.items():
            other = b.get(key)
            if other is None:
                side, point, why = _unmatched("OLD", record, list(b.values()))
                out.unmatched.append((side, prefix + point, why))
            elif "skipped" in record or "skipped" in other:
                skipped = record if "skipped" in record else other
                side = "OLD" if skipped is record else "NEW"
                out.unmatched.append(
                    (side, prefix + describe(record), f"not measured in {side} ({skipped['skipped']})")
                )
            else:
                c = change(record, other, rng, noise_pct)
                c.point = prefix + c.point
                out.changes.append(c)
        for key, record in b.items():
            if key not in a:
                side, point, why = _unmatched("NEW", record, list(a.values()))
                out.unmatched.append((side, prefix + point, why))
    if not out.changes:
        out.notes.append("no point was measured in both runs")
    return out


def _pct(x: float) -> str:
    if math.isinf(x):
        return "∞"
    return f"{x:+.1f}%"


def lines(comparison: Comparison, old_name: str, new_name: str) -> list[str]:
    """The comparison as plain text: a table of the changes, then the points not compared."""
    out = [f"OLD {old_name} ({comparison.machines[0]})", f"NEW {new_name} ({comparison.machines[1]})"]
    if comparison.changes:
        rows = [("point", "old ms", "new ms", "change", f"{CONFIDENCE:.0%} interval", "verdict")]
        for c in comparison.changes:
            interval = f"{_pct((c.low - 1) * 100)} to {_pct((c.high - 1) * 100)}"
            if c.method == "summary":
                interval += " (from summaries)"
            rows.append((c.point, f"{c.old_ms:.4g}", f"{c.new_ms:.4g}", _pct(c.change_pct), interval, c.verdict))
        widths = [max(len(row[i]) for row in rows) for i in range(len(rows[0]))]
        out.append("")
        for row in rows:
            out.append("  ".join(cell.ljust(w) for cell, w in zip(row, widths)).rstrip())
        counts = {v: sum(c.verdict == v for c in comparison.changes) for v in (SLOWER, FASTER, NOISE)}
        out.append("")
        out.append(", ".join(f"{n} {v}" for v, n in counts.items()) + f" (of {len(comparison.changes)} points)")
    for side, point, why in comparison.unmatched:
        out.append(f"{side} {point}: {why}")
    out += comparison.notes
    return out
