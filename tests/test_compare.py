"""raybench compare: a planted slowdown is found, a re-run of the same
distribution is within noise, points measured differently are not compared,
and the gate (--fail-slower) sets the exit status. Frame times are drawn
fresh each test (the rng fixture) from a distribution shaped like a real
run's: a few percent of jitter, and now and then a frame that stalls."""

import io
import json
import math
import sys

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
    # one frame a side: no interval can be had, and nothing is called, not even "within noise"
    one = compare.compare(run_of(rng, base, n=1, summary_only=True), run_of(rng, base, 2.0, n=1, summary_only=True))
    assert {c.verdict for c in one.changes} == {compare.TOO_FEW}
    shown = compare.lines(one, "old", "new")
    assert not any("100.0%" in line and "∞" in line for line in shown), shown  # not "-100% to ∞"
    assert sum(" none " in line and line.endswith(compare.TOO_FEW) for line in shown) == len(base)
    assert f"{len(base)} too few frames (of {len(base)} points)" in shown[-1]


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
    # an empty ramp, or one pair: no interval (was nan, "+nan%" and "within noise"; one pair was certain)
    for n in (0, 1):
        spheres[:] = list(range(20, 20 + 10 * n, 10))
        empty_old, empty_new = ramp([5.0]), ramp([9.0])
        empty_old["series"]["frame_ms"], empty_new["series"]["frame_ms"] = [5.0] * n, [9.0] * n
        (c,) = compare.compare([empty_old], [empty_new]).changes
        assert c.verdict == compare.TOO_FEW and not any(
            "nan" in line for line in compare.lines(compare.Comparison(changes=[c]), "o", "n")
        ), c


def test_the_drawn_medians_follow_the_resampled_medians_law(rng):
    """_median_ranks draws where a resample's median falls without drawing the
    resample; its law must be the resampling's own, which a direct resampling
    (np.median of n draws with replacement, the bootstrap as first written)
    measures here, for odd and even n, on values with a tie: the two
    histograms of medians agree within sampling error (total variation under
    0.02 over 40,000 draws; an off-by-one rank moves it past 0.1)."""
    for values in ([3.0, 1.0, 4.0, 1.0, 5.0, 9.0, 2.0], [3.0, 1.0, 4.0, 1.0, 5.0, 9.0, 2.0, 6.0]):
        ordered = np.sort(values)
        rounds = 40_000
        direct = np.median(ordered[rng.integers(0, ordered.size, (rounds, ordered.size))], axis=1)
        lo, hi = compare._median_ranks(ordered.size, rng, rounds)
        drawn = (ordered[lo] + ordered[hi]) / 2
        support = np.union1d(direct, drawn)
        p = np.searchsorted(support, direct)
        q = np.searchsorted(support, drawn)
        tv = 0.5 * np.abs(np.bincount(p, minlength=support.size) - np.bincount(q, minlength=support.size)).sum()
        assert tv / rounds < 0.02, (values, tv / rounds)


def test_the_paired_bootstrap_is_drawn_in_chunks(rng, monkeypatch):
    """The same interval, within sampling error, whatever the chunk (memory is
    bounded by it), and a very long ramp takes the normal law of its mean."""
    logs_old = rng.lognormal(0, 0.05, 300)
    logs_new = logs_old * rng.lognormal(math.log(1.05), 0.02, 300)
    whole = compare.paired_ratio(logs_old, logs_new, np.random.default_rng(1))
    monkeypatch.setattr(compare, "_CHUNK", 1000)  # 3 rounds a chunk
    chunked = compare.paired_ratio(logs_old, logs_new, np.random.default_rng(2))
    assert whole[0] == chunked[0] and np.allclose(whole[1:], chunked[1:], rtol=0.003)
    monkeypatch.setattr(compare, "_PAIRED_NORMAL", 100)
    normal = compare.paired_ratio(logs_old, logs_new, np.random.default_rng(3))
    assert normal[0] == whole[0] and np.allclose(normal[1:], whole[1:], rtol=0.003)


def test_matching_is_by_key_and_duplicates_are_named(rng, monkeypatch):
    """Unmatched points find their workload's kin by key, not by a scan of the
    other run (the scan was quadratic: 405 s for 10,000 points a side); a point
    recorded twice is named, and its later record compared."""
    base = medians(rng, 3)
    old, new = run_of(rng, base), run_of(rng, base)
    new.append(point(frames(rng, base[100], 60, 1.5), 100))  # 100 spheres again: a second record of that point
    for r in new:
        r["options"]["threads"] = 8 if r["spheres"] == 300 else r["options"]["threads"]
    result = compare.compare(old, new)
    assert [c.verdict for c in result.changes if c.point.endswith("100 spheres (accel bvh, threads 4)")] == [
        compare.SLOWER
    ]
    assert "NEW thesis test 4 cpu 800x600 100 spheres (accel bvh, threads 4) is recorded 2 times; " in "".join(
        result.notes
    )
    why = {text for _, _, text in result.unmatched}
    assert why == {"not comparable: the other run measured it with other options (threads 4 -> 8)"}
    monkeypatch.setattr(compare, "_NEAREST", 0)  # many option sets of one workload: counted, not searched
    why = {text for _, _, text in compare.compare(old, new).unmatched}
    assert why == {"not comparable: the other run measured it with 1 other sets of options"}


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


def test_cli_nothing_compared_fails_the_gate(tmp_path, rng, capsys):
    """--fail-slower 0 with no point in common exited 0: a gate that compared nothing passed."""
    old = write(tmp_path / "old.jsonl", run_of(rng, {100: 5.0}))
    other = write(tmp_path / "other.jsonl", run_of(rng, {200: 5.0}))
    assert run(["compare", str(old), str(other)]) == 0  # a report only: it says so
    assert "no point was measured in both runs" in capsys.readouterr().out
    assert run(["compare", str(old), str(other), "--fail-slower", "0"]) == 2
    captured = capsys.readouterr()
    assert captured.out == "" and captured.err.count("\n") == 1
    assert "nothing was compared" in captured.err and "Traceback" not in captured.err


def test_records_cannot_write_to_the_terminal(tmp_path, rng, capsys):
    """Option keys and values, skipped reasons and labels are shown escaped:
    no ESC, BEL or carriage return reaches the terminal, and a newline in a
    record cannot forge a line of the verdict."""
    old = point(frames(rng, 5.0, 30), 100)
    new = point(frames(rng, 5.0, 30), 100, options={"x\x1b]0;owned\x07": 1, "y\x1b[2J\r\nNEW forged": 2})
    skipped = {k: v for k, v in point(frames(rng, 5.0, 30), 100).items() if k not in ("frames", "frame_ms")}
    skipped.update(suite="scaling", test=None, skipped="slow\x1b[31m\rNEW forged line")
    result = compare.compare([old, skipped], [new])
    shown = compare.lines(result, "old", "new")
    text = "\n".join(shown)
    assert not any(c in text for c in "\x1b\x07\r"), text
    assert not any(line.startswith("NEW forged") for line in shown), shown
    assert "\\x1b]0;owned\\x07" in text and "\\r\\nNEW forged" in text and "\\rNEW forged line" in text
    # and through the command, whose stdout a terminal would obey
    a, b = write(tmp_path / "a.jsonl", [old, skipped]), write(tmp_path / "b.jsonl", [new])
    assert run(["compare", str(a), str(b)]) == 0
    out = capsys.readouterr().out
    assert not any(c in out for c in "\x1b\x07\r") and "\nNEW forged" not in out


class _Full(io.StringIO):
    """A standard output on a full disk (/dev/full): every write fails."""

    def write(self, text):
        raise OSError(28, "No space left on device")


def test_cli_stdout_that_cannot_be_written_is_one_line(tmp_path, rng, capsys, monkeypatch):
    """compare, schema and info --json writing to a full disk (/dev/full)
    raised OSError with a traceback."""
    old = write(tmp_path / "old.jsonl", run_of(rng, {100: 5.0}))
    for args in (["compare", str(old), str(old)], ["schema"], ["info", "--json"]):
        monkeypatch.setattr(sys, "stdout", _Full())
        assert run(args) == 2, args
        monkeypatch.undo()
        assert capsys.readouterr().err == "raybench: error: cannot write to standard output (No space left on device)\n"


def test_progress_shows_after_a_second(rng):
    """compare's progress: nothing in the first second, then at most a line a second."""
    from raybench.cli.out import Progress

    now = [0.0]
    stream = io.StringIO()
    progress = Progress("compare: points", clock=lambda: now[0], stream=stream)
    for done in range(1, 4001):
        now[0] = done / 1000  # a point a millisecond: 4 s in all
        progress(done, 4000)
    assert stream.getvalue().splitlines() == [f"compare: points: {n:,} of 4,000" for n in (1000, 2000, 3000, 4000)]
    calls = []
    base = medians(rng, 600)
    compare.compare(run_of(rng, base, n=5), run_of(rng, base, n=5), progress=lambda d, t: calls.append((d, t)))
    assert calls == [(256, 600), (512, 600)]


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


def test_a_noisy_point_is_marked_and_noted(rng):
    """A loaded machine's run: frames that vary by 30% leave an interval far
    wider than the noise floor, and "within noise" there would claim more than
    it knows: the verdict is marked noisy and a note says why (issue 40)."""
    base = medians(rng, 3)
    quiet = compare.compare(run_of(rng, base), run_of(rng, base))
    assert not any(c.noisy for c in quiet.changes) and not any("noise is high" in n for n in quiet.notes)
    loud = [point(frames(rng, m, 8) * rng.lognormal(0, 0.3, 8), s) for s, m in base.items()]
    noisy = compare.compare(run_of(rng, base), loud)
    marked = [c for c in noisy.changes if c.noisy]
    assert marked and all(c.verdict == compare.NOISE for c in marked)
    shown = compare.lines(noisy, "old", "new")
    assert sum(line.endswith("within noise (noisy)") for line in shown) == len(marked)
    assert any(line.startswith(f"noise is high: at {len(marked)} of 3 points") for line in shown), shown
    assert shown[2] == "" and shown[3].split()[:6] == ["point", "before", "ms", "after", "ms", "change"]
