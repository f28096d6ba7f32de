"""raybench compare: a planted slowdown is found, a re-run of the same
distribution is within noise, points measured differently are not compared,
and the gate (--fail-slower) sets the exit status. Frame times are drawn
fresh each test (the rng fixture) from a distribution shaped like a real
run's: a few percent of jitter, and now and then a frame that stalls."""

import json
import math

import numpy as np
import pytest

from raybench.bench import compare, results
from raybench.bench.results import ResultsWriter
from raybench.bench.stats import kept_samples, summarize
from raybench.cli import run

DATE = "2026-11-29T12:00:00+00:00"
MACHINE = {"cpu": {"model": "Synthetic CPU", "physical_cores": 4}, "gpus": []}


def frames(rng, median_ms, n, slowdown=1.0):
    """n frame times around median_ms: 3% log-normal jitter, and 1 frame in 20
    stalled by 20 to 60% (a page fault, another process)."""
    t = median_ms * rng.lognormal(0.0, 0.03, n)
    stalls = rng.random(n) < 0.05
    t[stalls] *= rng.uniform(1.2, 1.6, int(stalls.sum()))
    return t * slowdown


def point(samples, spheres, *, size=(800, 600), options=None, label="alpha", summary_only=False):
    r = {
        "suite": "thesis",
        "test": 4,
        "device": "cpu",
        "width": size[0],
        "height": size[1],
        "spheres": spheres,
        "options": {"accel": "bvh", "threads": 4, **(options or {})},
        "frames": len(samples),
        "frame_ms": summarize(samples),
        "kernel_ms": None,
        "run": {"id": label + "-1", "date": DATE, "label": label, "machine": MACHINE},
    }
    if not summary_only:
        r["samples_ms"] = kept_samples(samples)
    return r


def run_of(rng, medians, slowdown=1.0, n=60, **kw):
    return [point(frames(rng, m, n, slowdown), spheres, **kw) for spheres, m in medians.items()]


def medians(rng, points=8):
    return {100 * (i + 1): float(rng.uniform(2.0, 80.0)) for i in range(points)}


def write(path, records):
    with ResultsWriter(path) as w:
        for r in records:
            w.write(r)
    return path


def test_a_planted_slowdown_is_slower_and_a_rerun_within_noise(rng):
    base = medians(rng)
    old = run_of(rng, base)
    rerun = compare.compare(old, run_of(rng, base))
    assert [c.verdict for c in rerun.changes] == [compare.NOISE] * len(base), compare.lines(rerun, "old", "new")
    assert not rerun.unmatched
    slow = compare.compare(old, run_of(rng, base, slowdown=1.10))
    assert [c.verdict for c in slow.changes] == [compare.SLOWER] * len(base), compare.lines(slow, "old", "new")
    for c in slow.changes:
        assert c.method == "bootstrap"
        assert 5 < c.change_pct < 15
    fast = compare.compare(run_of(rng, base, slowdown=1.10), old)
    assert [c.verdict for c in fast.changes] == [compare.FASTER] * len(base)


def test_the_bootstrap_interval_covers_the_true_ratio(rng):
    """Over many draws, the 95% interval of the ratio of medians holds the true one
    about 95% of the time (not 50%, not always): it is an interval, not decoration.
    Over 1,000 draws the bounds below lie several standard deviations from the
    coverage such an interval has here (a little over 95%), so a fair interval
    does not fail them by chance, where a few hundred draws asked for misses
    sometimes would."""
    covered = 0
    trials = 1000
    for _ in range(trials):
        old = rng.lognormal(0.0, 0.05, 40)
        new = rng.lognormal(math.log(1.07), 0.05, 40)
        _, low, high = compare.bootstrap_ratio(old, new, rng, rounds=400)
        covered += low <= 1.07 <= high
    assert 0.90 * trials <= covered <= 0.99 * trials, covered


def test_summaries_alone_are_compared_by_the_normal_approximation(rng):
    """Records from before samples_ms: the median's error from p5, p95 and the frame count."""
    base = medians(rng)
    old = run_of(rng, base, n=200, summary_only=True)
    same = compare.compare(old, run_of(rng, base, n=200, summary_only=True))
    assert {c.method for c in same.changes} == {"summary"}
    assert {c.verdict for c in same.changes} == {compare.NOISE}
    slow = compare.compare(old, run_of(rng, base, slowdown=1.15, n=200, summary_only=True))
    assert {c.verdict for c in slow.changes} == {compare.SLOWER}
    # one frame a side: no interval can be had, and nothing is called
    one = compare.compare(run_of(rng, base, n=1, summary_only=True), run_of(rng, base, 2.0, n=1, summary_only=True))
    assert {c.verdict for c in one.changes} == {compare.NOISE}


def test_a_ramp_pairs_its_frames_by_sphere_count(rng):
    spheres = list(range(20, 1001, 10))
    old_ms = [0.01 * n * float(rng.lognormal(0, 0.03)) for n in spheres]

    def ramp(ms):
        r = point(ms, 1000)
        r.update(suite="test7", test=7, options={"accel": "none", "kernel": "fast"})
        r["series"] = {"spheres": spheres, "frame_ms": [float(x) for x in ms], "kernel_ms": None}
        del r["samples_ms"]
        return r

    new_ms = [x * 1.1 * float(rng.lognormal(0, 0.03)) for x in old_ms]
    (c,) = compare.compare([ramp(old_ms)], [ramp(new_ms)]).changes
    assert c.method == "paired" and c.verdict == compare.SLOWER and 1.05 < c.ratio < 1.15


def test_points_measured_differently_are_listed_not_compared(rng):
    base = medians(rng, 3)
    old = run_of(rng, base)
    new = run_of(rng, base)
    new[0]["options"]["threads"] = 2  # same workload, other options: not comparable
    new[1]["width"] = 1280  # another workload: only in each run
    result = compare.compare(old, new)
    assert len(result.changes) == 1
    why = {(side, text) for side, _, text in result.unmatched}
    assert ("OLD", "not comparable: the other run measured it with other options (threads 4 -> 2)") in why
    assert ("NEW", "only in NEW") in why and ("OLD", "only in OLD") in why
    skipped = {k: v for k, v in old[2].items() if k not in ("frames", "frame_ms", "kernel_ms", "samples_ms")}
    skipped.update(suite="scaling", skipped="predicted 4 s a frame, over the 1 s cap", test=None)
    measured = {**old[2], "suite": "scaling", "test": None}
    result = compare.compare([skipped], [measured])
    assert not result.changes and "not measured in OLD" in result.unmatched[0][2]


def test_runs_of_several_machines_are_matched_by_label(rng):
    base = medians(rng, 2)
    old = run_of(rng, base, label="alpha") + run_of(rng, base, label="beta")
    new = run_of(rng, base, label="alpha") + run_of(rng, base, 1.2, label="beta") + run_of(rng, base, label="gamma")
    result = compare.compare(old, new)
    verdicts = {c.point.split(":")[0]: c.verdict for c in result.changes}
    assert len(result.changes) == 4 and verdicts == {"alpha": compare.NOISE, "beta": compare.SLOWER}
    assert any("gamma is only in NEW" in n for n in result.notes)


def test_cli_gate_exit_status_and_table(tmp_path, rng, capsys):
    base = medians(rng, 4)
    old = write(tmp_path / "old.jsonl", run_of(rng, base))
    same = write(tmp_path / "same.jsonl", run_of(rng, base))
    slow = write(tmp_path / "slow.jsonl", run_of(rng, base, slowdown=1.10))
    assert run(["compare", str(old), str(same), "--fail-slower", "5"]) == 0
    out = capsys.readouterr().out
    assert "0 slower, 0 faster, 4 within noise (of 4 points)" in out
    assert run(["compare", str(old), str(slow), "--fail-slower", "5"]) == 1
    captured = capsys.readouterr()
    assert "4 slower" in captured.out
    assert captured.err.strip() == "raybench: compare: 4 points slower by 5% or more (--fail-slower 5)"
    assert run(["compare", str(old), str(slow), "--fail-slower", "30"]) == 0  # slower, but under the gate
    assert run(["compare", str(old), str(slow)]) == 0  # no gate: a report only
    capsys.readouterr()


@pytest.mark.parametrize(
    "args, message",
    [
        (["--fail-slower", "nan"], "--fail-slower: must be from 0 to 1000 percent, got nan"),
        (["--noise", "-1"], "--noise: must be from 0 to 1000 percent, got -1"),
    ],
)
def test_cli_bad_options_one_line(tmp_path, rng, capsys, args, message):
    old = write(tmp_path / "old.jsonl", run_of(rng, medians(rng, 1)))
    assert run(["compare", str(old), str(old), *args]) == 2
    assert capsys.readouterr().err == f"raybench: error: {message}\n"


def test_cli_bad_file_one_line(tmp_path, capsys):
    (tmp_path / "foreign.jsonl").write_text(json.dumps({"hello": 1}) + "\n")
    assert run(["compare", str(tmp_path / "missing.jsonl"), str(tmp_path / "foreign.jsonl")]) == 2
    assert capsys.readouterr().err.count("\n") == 1


def test_kept_samples_are_bounded_and_strided(rng):
    many = rng.uniform(1, 2, 25_000)
    kept = kept_samples(many)
    assert len(kept) == 1000 and kept[0] == float(f"{many[0]:.5g}") and kept[-1] == float(f"{many[-1]:.5g}")
    record = point(many, 10)
    results.check_record({"format": results.FORMAT, "version": results.VERSION, **record}, "record")
    # an even stride of a shuffled run: its median within a few standard errors (about 1%) of the whole's
    assert np.isclose(np.median(kept), np.median(many), rtol=0.05)
