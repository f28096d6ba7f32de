"""Two runs compared point by point: for each point measured in both, the
change in its median frame time with a confidence interval, and a verdict:
faster, slower, or within noise.

The interval is a bootstrap over frames where both records carry their
frames (samples_ms, recorded since results had them): each run's frames are
drawn again with replacement, BOOTSTRAP times, and the ratio of the two
medians taken each time; its 2.5th and 97.5th percentiles bound the change.
A resample's median is drawn without drawing the resample (_median_ranks:
where it falls in the sorted frames has a law of its own), so a point costs
BOOTSTRAP numbers whatever its frame count, and memory stays fixed.
A test-7 ramp pairs its frames by sphere count instead, and the bootstrap
draws the pairs, in chunks of fixed size. Records from before samples_ms carry only a summary; their
interval is the normal approximation of a median's error from the summary
(p5 to p95 spans 3.29 standard deviations of a normal distribution; a
median's standard error is 1.2533 sigma / sqrt(frames)), and the table says so.
Where a side has one frame there is no interval at all, and the verdict says
so (TOO_FEW) rather than calling it within noise.

A change is called faster or slower only when its interval excludes no
change AND the change is larger than the noise floor (asv's rule: both
significant and large enough); a re-run of one commit on one machine
differs by a few percent that no interval over frames captures (the
machine's state between runs), which the floor absorbs.

Points are matched by what was measured: suite, test, quantity, device,
size, spheres and options. Machines may differ (that is a comparison of
machines); a point of one run with no match in the other is listed, with
the fields in which its nearest point of the other run differs ("not
comparable"). Points are found by their key, so matching is linear in the
points; a point recorded twice in one run is named in the notes, and the
later record is the one compared.

Everything shown comes from a file someone may have edited: lines() escapes
every character that is not printable, so no record can move the terminal's
cursor, retitle it or forge a line of the verdict.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass, field

import numpy as np

from ..errors import RaybenchError, one_line

BOOTSTRAP = 2000
CONFIDENCE = 0.95
NOISE_PCT = 5.0
# z of the two-sided interval, and a normal distribution's p5 to p95 in sigmas
_Z = 1.959963984540054
_P5_P95_SIGMAS = 3.289707253902945

FASTER, SLOWER, NOISE = "faster", "slower", "within noise"
# one frame a side (or a ramp of one pair): no interval, so no verdict
TOO_FEW = "too few frames"
# Elements of one chunk of a paired bootstrap: fixed memory whatever the ramp's length.
_CHUNK = 1 << 20
# Past this many pairs the paired bootstrap's mean is normal to far within its own
# sampling error, and is taken as such (the work would grow with the pairs otherwise).
_PAIRED_NORMAL = 4096
# Other option sets of one workload searched for the nearest (an unmatched point's "why").
_NEAREST = 64
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
    noise_pct: float = NOISE_PCT

    @property
    def change_pct(self) -> float:
        return (self.ratio - 1.0) * 100.0

    @property
    def noisy(self) -> bool:
        """Within noise, but with an interval reaching past the noise floor on a
        side: a change of the floor's size there would not have been seen."""
        floor = 1 + self.noise_pct / 100
        return self.verdict == NOISE and (self.high > floor or self.low < 1 / floor)


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
    return int((record.get("samples") if record["suite"] == "parts" else record.get("frames")) or 0)


def _kept(record: dict) -> int:
    """How many frame times the record keeps (a list, or an array: results.read(compact=True))."""
    samples = record.get("samples_ms")
    return 0 if samples is None else len(samples)


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


def _median_ranks(n: int, rng: np.random.Generator, rounds: int) -> tuple[np.ndarray, np.ndarray]:
    """Where the median of each of `rounds` resamples (n draws with
    replacement) of n sorted values falls: the indices of its two middle
    values (one and the same for an odd n), drawn without drawing the
    resamples. A resample is floor(n U) for n uniform U; floor keeps order, so
    its k-th smallest index is floor(n U_(k)), and U_(k) of n uniforms is
    Beta(k, n - k + 1); the next one up is U_(k) + (1 - U_(k)) Beta(1, n - k),
    the least of the n - k above it. np.median of an even count averages the
    two middle ones."""
    k = (n + 1) // 2  # the (lower) middle rank, from 1
    low = rng.beta(k, n - k + 1, rounds)
    lo = np.minimum((low * n).astype(np.int64), n - 1)
    if n % 2:
        return lo, lo
    high = low + (1 - low) * rng.beta(1, n - k, rounds)
    return lo, np.minimum((high * n).astype(np.int64), n - 1)


class _Ranks:
    """_median_ranks by frame count, drawn once for each side: the medians'
    law depends on n alone, so every point of one side and frame count shares
    the draws (each point's interval is still its own bootstrap's), and a
    point costs a gather of BOOTSTRAP values. The two sides never share
    draws: their medians must be independent."""

    def __init__(self, rng: np.random.Generator, rounds: int):
        self.rng, self.rounds = rng, rounds
        self.drawn: dict[tuple[int, int], tuple[np.ndarray, np.ndarray]] = {}

    def medians(self, side: int, ordered: np.ndarray) -> np.ndarray:
        key = (side, ordered.size)
        if key not in self.drawn:
            self.drawn[key] = _median_ranks(ordered.size, self.rng, self.rounds)
        lo, hi = self.drawn[key]
        return (ordered[lo] + ordered[hi]) / 2


def _median(ordered: np.ndarray) -> float:
    n = ordered.size
    return float((ordered[(n - 1) // 2] + ordered[n // 2]) / 2)


def _bounds(draws: np.ndarray) -> tuple[float, float]:
    """The draws' CONFIDENCE interval: np.percentile's linear interpolation, on one sort."""
    draws = np.sort(draws)
    out = []
    for q in ((1 - CONFIDENCE) / 2, (1 + CONFIDENCE) / 2):
        at = q * (draws.size - 1)
        below = int(at)
        above = min(below + 1, draws.size - 1)
        out.append(float(draws[below] + (draws[above] - draws[below]) * (at - below)))
    return out[0], out[1]


def bootstrap_ratio(
    old, new, rng: np.random.Generator, rounds: int = BOOTSTRAP, ranks: _Ranks | None = None
) -> tuple[float, float, float]:
    """The ratio of new's median to old's, and its bootstrap interval at
    CONFIDENCE. ranks: draws shared with other points (compare()'s); else fresh."""
    ranks = ranks if ranks is not None else _Ranks(rng, rounds)
    old = np.sort(np.asarray(old, dtype=np.float64))
    new = np.sort(np.asarray(new, dtype=np.float64))
    low, high = _bounds(ranks.medians(1, new) / ranks.medians(0, old))
    return _median(new) / _median(old), low, high


def paired_ratio(old, new, rng: np.random.Generator, rounds: int = BOOTSTRAP) -> tuple[float, float, float]:
    """The geometric mean of new/old over paired frames, and its bootstrap
    interval, drawn in chunks of at most _CHUNK values."""
    logs = np.log(np.asarray(new, dtype=np.float64) / np.asarray(old, dtype=np.float64))
    mean = float(logs.mean())
    if logs.size > _PAIRED_NORMAL:
        half = _Z * float(logs.std()) / math.sqrt(logs.size)
        return math.exp(mean), math.exp(mean - half), math.exp(mean + half)
    draws = np.empty(rounds)
    step = max(1, _CHUNK // logs.size)
    for start in range(0, rounds, step):
        count = min(step, rounds - start)
        draws[start : start + count] = logs[rng.integers(0, logs.size, (count, logs.size))].mean(axis=1)
    low, high = _bounds(draws)
    return math.exp(mean), math.exp(low), math.exp(high)


def judge(ratio: float, low: float, high: float, noise_pct: float) -> str:
    """faster or slower only if the interval excludes 1 and the change passes the floor
    (symmetric in log: 5% slower is 1.05x the time, 5% faster 1/1.05x)."""
    if not all(math.isfinite(x) and x > 0 for x in (ratio, low, high)):
        return TOO_FEW  # no interval (one frame a side): nothing can be called, not even "within noise"
    floor = math.log1p(noise_pct / 100)
    if low > 1 and math.log(ratio) > floor:
        return SLOWER
    if high < 1 and -math.log(ratio) > floor:
        return FASTER
    return NOISE


def change(
    old: dict, new: dict, rng: np.random.Generator, noise_pct: float = NOISE_PCT, ranks: _Ranks | None = None
) -> Change:
    """The change of one point from old's record to new's."""
    old_ms, new_ms = _times(old)["median"], _times(new)["median"]
    if (
        old["suite"] == "test7"
        and old["series"]["spheres"] == new["series"]["spheres"]
        and len(old["series"]["spheres"]) >= 2
    ):
        ratio, low, high = paired_ratio(old["series"]["frame_ms"], new["series"]["frame_ms"], rng)
        method = "paired"
        old_ms, new_ms = sum(old["series"]["frame_ms"]), sum(new["series"]["frame_ms"])
    elif _kept(old) >= 2 and _kept(new) >= 2:
        ratio, low, high = bootstrap_ratio(old["samples_ms"], new["samples_ms"], rng, ranks=ranks)
        method = "bootstrap"
    else:
        ratio = new_ms / old_ms
        spread = _summary_interval(old, new)
        # one frame a side: no interval at all, so nothing can be called
        low, high = (ratio * math.exp(spread[0]), ratio * math.exp(spread[1])) if spread else (math.nan, math.nan)
        method = "summary"
    verdict = judge(ratio, low, high, noise_pct)
    return Change(describe(new), old_ms, new_ms, ratio, low, high, method, verdict, noise_pct)


def _measured(records: list[dict], side: str, notes: list[str]) -> dict[str, dict[tuple, dict]]:
    """Records by machine label, then by identity; the later record of a point
    measured twice wins, and a note names the point."""
    out: dict[str, dict[tuple, dict]] = {}
    twice: dict[tuple, int] = {}
    for r in records:
        label, key = r["run"]["label"], identity(r)
        points = out.setdefault(label, {})
        if key in points:
            twice[(label, key)] = twice.get((label, key), 1) + 1
        points[key] = r
    for (label, key), times in twice.items():
        notes.append(f"{side} {describe(out[label][key])} is recorded {times} times; the last record is compared")
    return out


def _workload(record: dict) -> tuple:
    """A record's identity but its options: the same workload, however it was measured."""
    return tuple(record.get(k) for k in IDENTITY if k != "options")


def _option_changes(a: dict, b: dict) -> list[str]:
    oa, ob = a.get("options") or {}, b.get("options") or {}
    return [f"{k} {oa.get(k, '-')} -> {ob.get(k, '-')}" for k in sorted(set(oa) | set(ob)) if oa.get(k) != ob.get(k)]


def _by_workload(records) -> dict[tuple, list[dict]]:
    out: dict[tuple, list[dict]] = {}
    for r in records:
        out.setdefault(_workload(r), []).append(r)
    return out


def _unmatched(side: str, record: dict, others: dict[tuple, list[dict]]) -> tuple[str, str, str]:
    """Why a point has no match: skipped on its side, measured with other
    options in the other run (the same workload: not comparable), or absent
    there. others: the other run's records by workload (_by_workload)."""
    if "skipped" in record:
        return side, describe(record), f"not measured in {side} ({record['skipped']})"
    kin = others.get(_workload(record), [])
    if not kin:
        return side, describe(record), f"only in {side}"
    if len(kin) > _NEAREST:
        why = f"not comparable: the other run measured it with {len(kin)} other sets of options"
        return side, describe(record), why
    nearest = min(kin, key=lambda o: len(_option_changes(record, o)))
    old, new = (record, nearest) if side == "OLD" else (nearest, record)
    return (
        side,
        describe(record),
        "not comparable: the other run measured it with other options (" + ", ".join(_option_changes(old, new)) + ")",
    )


def compare(old: list[dict], new: list[dict], noise_pct: float = NOISE_PCT, seed: int = 0, progress=None) -> Comparison:
    """old's and new's records (results.read), compared point by point.
    A run holding several machines (bench --scheduler) is matched machine by
    machine, by label; two runs of one machine each are compared whatever
    their labels (two machines, or one machine twice). progress, where
    given, is called now and then with (points done, points in all)."""
    if not 0 <= noise_pct <= 1000 or math.isnan(noise_pct):
        raise RaybenchError(f"--noise: must be from 0 to 1000 percent, got {noise_pct:g}")
    rng = np.random.default_rng(seed)
    ranks = _Ranks(rng, BOOTSTRAP)
    out = Comparison()
    sides = _measured(old, "OLD", out.notes), _measured(new, "NEW", out.notes)
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
    total, done = sum(len(sides[0][p[0]]) for p in pairs), 0
    for old_label, new_label in pairs:
        a, b = sides[0][old_label], sides[1][new_label]
        a_work, b_work = _by_workload(a.values()), _by_workload(b.values())
        prefix = f"{old_label}: " if len(pairs) > 1 else ""
        for key, record in a.items():
            done += 1
            if progress is not None and done % 256 == 0:
                progress(done, total)
            other = b.get(key)
            if other is None:
                side, point, why = _unmatched("OLD", record, b_work)
                out.unmatched.append((side, prefix + point, why))
            elif "skipped" in record or "skipped" in other:
                skipped = record if "skipped" in record else other
                side = "OLD" if skipped is record else "NEW"
                out.unmatched.append(
                    (side, prefix + describe(record), f"not measured in {side} ({skipped['skipped']})")
                )
            else:
                c = change(record, other, rng, noise_pct, ranks)
                c.point = prefix + c.point
                out.changes.append(c)
        for key, record in b.items():
            if key not in a:
                side, point, why = _unmatched("NEW", record, a_work)
                out.unmatched.append((side, prefix + point, why))
    if not out.changes:
        out.notes.append("no point was measured in both runs")
    noisy = sum(c.noisy for c in out.changes)
    if noisy:
        out.notes.append(
            f"noise is high: at {noisy} of {len(out.changes)} points the {CONFIDENCE:.0%} interval reaches past "
            f"±{noise_pct:g}%, so a change of that size there would not be seen (marked 'noisy'; a busy machine? "
            "more frames, or a quieter machine)"
        )
    return out


def _pct(x: float) -> str:
    if math.isinf(x):
        return "∞"
    return f"{x:+.1f}%"


def _interval(c: Change) -> str:
    if not (math.isfinite(c.low) and math.isfinite(c.high)):
        return "none"
    text = f"{_pct((c.low - 1) * 100)} to {_pct((c.high - 1) * 100)}"
    return text + " (from summaries)" if c.method == "summary" else text


def lines(comparison: Comparison, old_name: str, new_name: str) -> list[str]:
    """The comparison as plain text: a table of the changes (point, before,
    after, change, its interval, verdict), then the points not compared, then
    the notes. Every line is one line of printable text (errors.one_line):
    what a record holds is shown escaped, never obeyed by the terminal."""
    out = [f"OLD {old_name} ({comparison.machines[0]})", f"NEW {new_name} ({comparison.machines[1]})"]
    if comparison.changes:
        rows = [("point", "before ms", "after ms", "change", f"{CONFIDENCE:.0%} interval", "verdict")]
        for c in comparison.changes:
            verdict = c.verdict + (" (noisy)" if c.noisy else "")
            rows.append(
                (one_line(c.point), f"{c.old_ms:.4g}", f"{c.new_ms:.4g}", _pct(c.change_pct), _interval(c), verdict)
            )
        widths = [max(len(row[i]) for row in rows) for i in range(len(rows[0]))]
        out.append("")
        for row in rows:
            out.append("  ".join(cell.ljust(w) for cell, w in zip(row, widths)).rstrip())
        counts = {v: sum(c.verdict == v for c in comparison.changes) for v in (SLOWER, FASTER, NOISE, TOO_FEW)}
        if not counts[TOO_FEW]:
            del counts[TOO_FEW]
        out.append("")
        out.append(", ".join(f"{n} {v}" for v, n in counts.items()) + f" (of {len(comparison.changes)} points)")
    for side, point, why in comparison.unmatched:
        out.append(f"{side} {point}: {why}")
    out += comparison.notes
    return [one_line(line) for line in out]
