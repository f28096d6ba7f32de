"""The report (raybench.bench.report): its verdicts on synthetic records, on
both sides of every claim's threshold, loading results files, and the
report folder end to end. The timings are random (a fresh seed per test, see
the rng fixture) so that the rules are tested, not one hand-picked dataset."""

import functools
import re
import statistics

import numpy as np
import pytest
from PIL import Image

from raybench import RaybenchError
from raybench.bench import report
from raybench.bench.report import FAILS, HOLDS, NOT_MEASURED
from raybench.bench.results import ResultsWriter
from raybench.cli import run

SIZES = [(800, 600), (1280, 800), (1680, 1050)]
COUNTS = list(range(100, 1001, 100))
RAMP = list(range(20, 1001, 10))
BLOCKS = [[2, 2], [4, 4], [8, 8], [16, 16], [32, 32], [32, 8], [8, 32], [16, 32]]
THREADS = {"1 thread": 1, "half the cores": 2, "all cores": 4, "2x cores": 8, "one per row": 1050}
DATE = "2024-05-01T12:00:00+00:00"


# report columns: machine label and kernel (records without one are simple-kernel records)
A, B = "alpha, simple kernel", "beta, simple kernel"


def machine(cpu_gflops=200.0, gpu_gflops=10000.0):
    return {
        "cpu": {"model": "Synthetic CPU", "physical_cores": 4, "logical_cpus": 8, "fp32_gflops": cpu_gflops},
        "gpus": [{"name": "Synthetic GPU", "multiprocessors": 40, "fp32_gflops": gpu_gflops}],
    }


def ms(median):
    return {"median": float(median), "p5": 0.9 * float(median), "p95": 1.1 * float(median)}


def set_at(path, value):
    """A change to a record: the value at path (keys and indices) set to value."""

    def change(r):
        *head, last = path
        target = r
        for key in head:
            target = target[key]
        target[last] = value

    return change


def rec(
    suite,
    device,
    spheres,
    median,
    *,
    size=(800, 600),
    kernel=None,
    options=None,
    test=None,
    label="alpha",
    date=DATE,
    mach=None,
    series=None,
):
    """One record with every field report._check requires (and what the runner writes besides)."""
    r = {
        "suite": suite,
        "test": test,
        "device": device,
        "width": size[0],
        "height": size[1],
        "spheres": spheres,
        "options": options or {},
        "frame_ms": ms(median),
        "kernel_ms": ms(kernel) if kernel is not None else None,
        "run": {"id": f"{label}-{date}", "date": date, "label": label, "machine": mach or machine()},
    }
    if series is not None:
        r["series"] = series
    return r


def thesis(rng, **kw):
    """Tests 1-6: CPU and GPU frame times exactly linear in the sphere count, the
    GPU 5 to 50 times faster in slope and intercept (so faster at every point)."""
    out = []
    for size in SIZES:
        cs, ci = rng.uniform(0.05, 0.5), rng.uniform(1, 20)
        gs, gi = cs / rng.uniform(5, 50), ci / rng.uniform(5, 50)
        for n in COUNTS:
            out.append(rec("thesis", "cpu", n, cs * n + ci, size=size, options={"threads": 8}, **kw))
            out.append(
                rec(
                    "thesis",
                    "cuda",
                    n,
                    gs * n + gi,
                    size=size,
                    kernel=0.8 * (gs * n + gi),
                    options={"block": [32, 32]},
                    **kw,
                )
            )
    return out


def ramp(rng, device="cuda", kink=False, **kw):
    """Test 7's ramp: one frame per sphere count, linear, or with the slope
    multiplied by 30 past 500 spheres (a hockey stick no line fits)."""
    slope, icpt = rng.uniform(0.001, 0.1), rng.uniform(0.5, 5)
    x = np.array(RAMP, dtype=float)
    y = slope * x + icpt + (30 * slope * np.maximum(x - 500, 0) if kink else 0)
    return rec(
        "test7",
        device,
        1000,
        float(np.median(y)),
        test=7,
        series={"spheres": RAMP, "frame_ms": y.tolist(), "kernel_ms": None},
        **kw,
    )


def gpu_tuning(frame, kernel=None, **kw):
    return [
        rec(
            "tuning",
            "cuda",
            1000,
            f,
            size=(1680, 1050),
            kernel=None if kernel is None else kernel[i],
            options={"block": b},
            **kw,
        )
        for i, (b, f) in enumerate(zip(BLOCKS, frame))
    ]


def cpu_tuning(times, **kw):
    return [
        rec("tuning", "cpu", 1000, t, size=(1680, 1050), options={"threads": THREADS[name], "label": name}, **kw)
        for name, t in times.items()
    ]


def constant(device, ratios, rng, kernel_ratios=None, **kw):
    """Constant-vs-runtime pairs at three counts, runtime = constant x ratio
    (frame times), and kernel times with kernel_ratios where given."""
    kernel_ratios = [None] * 3 if kernel_ratios is None else kernel_ratios
    out = []
    for n, ratio, kr in zip([100, 500, 1000], ratios, kernel_ratios):
        c, k = rng.uniform(5, 50), rng.uniform(1, 4)
        for mode, f in (("constant", 1.0), ("runtime", ratio)):
            kernel = None if kr is None else k * (1.0 if mode == "constant" else kr)
            out.append(rec("constant-vs-runtime", device, n, c * f, kernel=kernel, options={"count": mode}, **kw))
    return out


def verdict(records, claim):
    return report.verdicts(records)[claim - 1]


def ref_r2(x, y):
    """R² of the least-squares line, from numpy.polyfit: the independent reference."""
    slope, icpt = np.polyfit(x, y, 1)
    y = np.asarray(y)
    return 1 - ((y - (slope * np.asarray(x) + icpt)) ** 2).sum() / ((y - y.mean()) ** 2).sum()


# --- the pure functions ---------------------------------------------------------------


def test_speedups_are_cpu_over_gpu_medians_of_matched_points(rng):
    """Speedups match CPU to GPU by (width, height, spheres) within the thesis suite
    only; a GPU point with no CPU twin, and other suites' points, are ignored."""
    records = thesis(rng)
    records.append(rec("thesis", "cuda", 1100, 1.0))
    records.append(rec("constant-vs-runtime", "cuda", 500, 1e6, options={"count": "runtime"}))
    sp = report.speedups(records)
    medians = {
        (r["device"], r["width"], r["height"], r["spheres"]): r["frame_ms"]["median"]
        for r in records
        if r["suite"] == "thesis"
    }
    assert [(p["width"], p["height"], p["spheres"]) for p in sp] == [(w, h, n) for w, h in SIZES for n in COUNTS]
    for p in sp:
        key = (p["width"], p["height"], p["spheres"])
        assert p["speedup"] == pytest.approx(medians[("cpu", *key)] / medians[("cuda", *key)])


def test_series_fits_agree_with_numpy_polyfit(rng):
    """The lines drawn and judged for claim 2 are numpy's own least squares."""
    records = thesis(rng)
    for r in records:  # noise, so that the fit is not trivially exact
        r["frame_ms"]["median"] *= rng.uniform(0.9, 1.1)
    series = report.thesis_series(records)
    assert len(series) == 2 * len(SIZES)
    for s in series:
        assert s["spheres"] == COUNTS
        slope, icpt = np.polyfit(s["spheres"], s["median"], 1)
        assert s["fit"]["slope"] == pytest.approx(slope) and s["fit"]["intercept"] == pytest.approx(icpt)
        assert s["fit"]["r2"] == pytest.approx(ref_r2(s["spheres"], s["median"]))


@pytest.mark.parametrize("gpu_over_cpu", ["equal", "slower"])
def test_claim1_gpu_faster_everywhere(rng, gpu_over_cpu):
    records = thesis(rng)
    v = verdict(records, 1)
    assert v["verdict"] == HOLDS and v["values"]["n"] == len(SIZES) * len(COUNTS)
    # One point where the GPU is as slow as the CPU, or slower: the claim fails.
    gpu = rng.choice([r for r in records if r["device"] == "cuda"])
    cpu = next(
        r for r in records if r["device"] == "cpu" and r["width"] == gpu["width"] and r["spheres"] == gpu["spheres"]
    )
    gpu["frame_ms"]["median"] = cpu["frame_ms"]["median"] * (1.0 if gpu_over_cpu == "equal" else rng.uniform(1.01, 3))
    v = verdict(records, 1)
    assert v["verdict"] == FAILS and v["values"]["not_faster"] == 1 and v["values"]["min"] <= 1


@pytest.mark.parametrize("where", ["thesis", "test7"])
def test_claim2_linear_holds_kink_fails(rng, where):
    """Exactly linear data holds; one hockey-stick series (R² well below 0.98
    by numpy's own fit) fails, and is the one named as least linear."""
    records = thesis(rng) + [ramp(rng, "cpu"), ramp(rng, "cuda")]
    v = verdict(records, 2)
    assert v["verdict"] == HOLDS and v["values"]["min_r2"] == pytest.approx(1.0)
    assert v["values"]["n"] == 2 * len(SIZES) + 2
    if where == "test7":
        records[-1] = ramp(rng, "cuda", kink=True)
        x, y = RAMP, records[-1]["series"]["frame_ms"]
    else:
        w, h = SIZES[rng.integers(len(SIZES))]
        kinked = [r for r in records if r["suite"] == "thesis" and r["device"] == "cuda" and r["width"] == w]
        slope = kinked[1]["frame_ms"]["median"] - kinked[0]["frame_ms"]["median"]
        for r in kinked:
            r["frame_ms"]["median"] += 0.3 * slope * max(r["spheres"] - 500, 0)
        x, y = COUNTS, [r["frame_ms"]["median"] for r in kinked]
    expected = ref_r2(x, y)
    assert expected < report.R2_MIN  # the data really are on the failing side
    v = verdict(records, 2)
    assert v["verdict"] == FAILS and len(v["values"]["below"]) == 1
    assert v["values"]["min_r2"] == pytest.approx(expected)


@pytest.mark.parametrize(
    "share,expected", [(0.67, HOLDS), (1.49, HOLDS), ("inside", HOLDS), (0.66, FAILS), (1.51, FAILS), ("far", FAILS)]
)
def test_claim3_speedup_against_theoretical_ratio(rng, share, expected):
    """The machine's GPU FP32 rate is set so that median speedup / theoretical
    ratio is `share`: inside [2/3, 3/2] holds, outside fails."""
    if share == "inside":
        share = rng.uniform(0.7, 1.45)
    elif share == "far":
        share = rng.choice([rng.uniform(0.05, 0.6), rng.uniform(1.6, 20)])
    mach = machine(cpu_gflops=rng.uniform(50, 500))
    records = thesis(rng, mach=mach)
    median = statistics.median(p["cpu_ms"] / p["cuda_ms"] for p in report.speedups(records))
    mach["gpus"][0]["fp32_gflops"] = mach["cpu"]["fp32_gflops"] * median / share
    v = verdict(records, 3)
    assert v["verdict"] == expected and v["values"]["share"] == pytest.approx(share)
    mach["gpus"][0]["fp32_gflops"] = None  # no rate: no verdict
    assert verdict(records, 3)["verdict"] == NOT_MEASURED


@pytest.mark.parametrize("with_kernel", [False, True])
@pytest.mark.parametrize("rel,expected", [("fastest", HOLDS), ("within 5%", HOLDS), (1.06, FAILS), (1.10, FAILS)])
def test_claim4_32x32_near_the_fastest(rng, rel, expected, with_kernel):
    """32x32 at most 5% slower than the fastest shape holds. The kernel time is
    judged where measured, even when the frame times say the opposite; and a
    smaller tuning size where 32x32 is slow is ignored (the largest is judged)."""
    rel = {"fastest": rng.uniform(0.5, 1), "within 5%": rng.uniform(1.001, 1.049)}.get(rel, rel)
    judged, opposite = rng.uniform(5, 20, len(BLOCKS)), rng.uniform(1, 40, len(BLOCKS))
    i = BLOCKS.index([32, 32])
    judged[i] = np.delete(judged, i).min() * rel
    opposite[i] = np.delete(opposite, i).min() * (1.2 if expected == HOLDS else 0.9)
    records = gpu_tuning(opposite, kernel=judged) if with_kernel else gpu_tuning(judged)
    small = [rec("tuning", "cuda", 100, 1.0 if b != [32, 32] else 9.0, options={"block": b}) for b in BLOCKS]
    v = verdict(records + small, 4)
    assert v["verdict"] == expected and v["values"]["relative"] == pytest.approx(max(rel, 1.0))
    no_32 = [r for r in records if r["options"]["block"] != [32, 32]]
    assert verdict(no_32, 4)["verdict"] == NOT_MEASURED


def test_claim4_does_not_mix_kernel_and_frame_times(rng):
    """Kernel times decide only where every shape has one: a 32x32 whose frame
    is 2x the fastest's must not 'hold' because only it has a (much smaller)
    kernel time."""
    frame = rng.uniform(5, 20, len(BLOCKS))
    i = BLOCKS.index([32, 32])
    frame[i] = 2 * np.delete(frame, i).min()
    records = gpu_tuning(frame)
    records[i]["kernel_ms"] = ms(0.1 * frame[i])
    assert verdict(records, 4)["verdict"] == FAILS


def cpu_times(rng, two_x_ok=True, per_row_ok=True):
    """CPU tuning times with "all cores" fastest; "2x cores" 0.1-4.9% or 10-50%
    slower than it, "one per row" slower or faster than "1 thread"."""
    one = rng.uniform(50, 100)
    t = {"1 thread": one, "half the cores": one / rng.uniform(1.5, 2), "all cores": one / rng.uniform(3, 4)}
    t["2x cores"] = t["all cores"] * (rng.uniform(1.001, 1.049) if two_x_ok else rng.uniform(1.1, 1.5))
    t["one per row"] = one * (rng.uniform(1.05, 3) if per_row_ok else rng.uniform(0.5, 0.95))
    return t


@pytest.mark.parametrize("two_x_ok", [True, False])
@pytest.mark.parametrize("per_row_ok", [True, False])
def test_claim5_both_halves(rng, two_x_ok, per_row_ok):
    """Both halves measured: the claim holds only if both do."""
    v = verdict(cpu_tuning(cpu_times(rng, two_x_ok, per_row_ok)), 5)
    assert v["verdict"] == (HOLDS if two_x_ok and per_row_ok else FAILS)
    assert v["values"]["two_x_ok"] == two_x_ok and v["values"]["per_row_ok"] == per_row_ok


@pytest.mark.parametrize("missing", ["one per row", "1 thread", "2x cores"])
@pytest.mark.parametrize("ok", [True, False])
def test_claim5_one_half_measured(rng, missing, ok):
    """With one half unmeasured the claim cannot hold: the measured half
    failing makes it fail, holding leaves it not measured."""
    times = cpu_times(rng, two_x_ok=ok, per_row_ok=ok)
    del times[missing]
    v = verdict(cpu_tuning(times), 5)
    assert v["verdict"] == (NOT_MEASURED if ok else FAILS)
    assert "not measured" in v["measured"]


@pytest.mark.parametrize("with_kernel", [False, True])
@pytest.mark.parametrize("gpu_ok", [True, False])
def test_claim6_gpu_ratios_decide_cpu_ratios_do_not(rng, gpu_ok, with_kernel):
    """Every GPU runtime/constant ratio must be above 1.02, in kernel time where
    measured (even when the frame times say the opposite); the CPU's ratios,
    either side of 1, change nothing."""
    ratios = rng.uniform(1.021, 2, 3)
    if not gpu_ok:  # slower at runtime, but by less than 2%, at one count
        ratios[rng.integers(3)] = rng.uniform(1.0, 1.019)
    opposite = rng.uniform(0.7, 0.99, 3) if gpu_ok else rng.uniform(1.1, 2, 3)
    gpu = constant("cuda", opposite, rng, kernel_ratios=ratios) if with_kernel else constant("cuda", ratios, rng)
    cpu_ratios = rng.uniform(0.5, 2, 3)
    for cpu in (cpu_ratios, 1 / cpu_ratios):
        v = verdict(gpu + constant("cpu", cpu, rng), 6)
        assert v["verdict"] == (HOLDS if gpu_ok else FAILS)
        assert v["values"]["gpu"] == pytest.approx(ratios) and v["values"]["cpu"] == pytest.approx(cpu)
    assert verdict(constant("cpu", ratios, rng), 6)["verdict"] == NOT_MEASURED


def test_every_claim_not_measured_without_its_data(rng):
    assert [v["verdict"] for v in report.verdicts([])] == [NOT_MEASURED] * 6
    # CPU-only data, a GPU tuning without 32x32, an unpaired constant point: only claim 2 measurable.
    records = [r for r in thesis(rng) if r["device"] == "cpu"]
    records += [
        rec("tuning", "cuda", 1000, 5.0, options={"block": [16, 16]}),
        rec("constant-vs-runtime", "cuda", 500, 5.0, options={"count": "constant"}),
    ]
    assert [v["verdict"] for v in report.verdicts(records)] == [NOT_MEASURED, HOLDS] + [NOT_MEASURED] * 4


# --- loading -----------------------------------------------------------------------------


def write(path, records):
    with ResultsWriter(path) as w:
        for r in records:
            w.write(r)
    return path


def test_load_keeps_the_later_run_of_a_point(tmp_path, rng):
    """A point measured twice under one label: the later run by date wins,
    whichever file comes first; at equal dates, the later file."""
    t_early, t_late = rng.uniform(1, 100, 2)
    late = write(
        tmp_path / "late.jsonl",
        [
            rec("thesis", "cpu", 500, t_late, date="2024-05-02T09:00:00+00:00"),
            rec("thesis", "cpu", 600, 1.0, label="beta"),
        ],
    )
    early = write(
        tmp_path / "early.jsonl",
        [rec("thesis", "cpu", 500, t_early, date="2024-05-01T23:00:00+00:00"), rec("thesis", "cpu", 100, 1.0)],
    )
    for paths in ([late, early], [early, late]):
        machines, notes = report.load(paths)
        at = {r["spheres"]: r["frame_ms"]["median"] for r in machines[A]}
        assert at == {500: t_late, 100: 1.0}
        assert len(machines[B]) == 1 and any("more than once" in n for n in notes)
    assert list(report.load([late, early])[0]) == [A, B]  # columns in the order first seen
    same = write(tmp_path / "same.jsonl", [rec("thesis", "cpu", 500, t_early, date="2024-05-02T09:00:00+00:00")])
    assert report.load([late, same])[0][A][0]["frame_ms"]["median"] == t_early


def test_load_skips_a_truncated_last_line(tmp_path, rng):
    path = write(tmp_path / "r.jsonl", thesis(rng)[:3])
    with open(path, "a") as f:
        f.write('{"format": "raybench-results", "version": 1, "suite": "th')
    with pytest.warns(UserWarning, match="cut short"):
        machines, notes = report.load([path])
    assert len(machines[A]) == 3 and any("cut short" in n for n in notes)


def _drop(*keys):
    return lambda r: functools.reduce(dict.get, keys[:-1], r).pop(keys[-1])


@pytest.mark.parametrize(
    "change,needle",
    [
        (_drop("suite"), "suite"),
        (_drop("device"), "device"),
        (_drop("width"), "width"),
        (_drop("height"), "height"),
        (_drop("spheres"), "spheres"),
        (_drop("frame_ms"), "frame_ms"),
        (_drop("frame_ms", "p95"), "frame_ms"),
        (_drop("run", "label"), "run"),
        (_drop("run"), "run"),
        (lambda r: r.update(kernel_ms={"median": 1.0}), "kernel_ms"),
        (lambda r: r.update(spheres=500.0), "spheres"),
        (lambda r: r.update(options=[1]), "options"),
        (_drop("series"), "series"),
        (lambda r: r["series"]["frame_ms"].pop(), "series"),
    ],
)
def test_load_names_a_missing_field(tmp_path, rng, change, needle):
    records = [thesis(rng)[0], ramp(rng)]
    change(records[1])
    path = write(tmp_path / "bad.jsonl", records)
    with pytest.raises(RaybenchError) as info:
        report.load([path])
    message = str(info.value)
    assert "\n" not in message and needle in message and "bad.jsonl" in message and "line 2" in message


# --- the report folder ---------------------------------------------------------------------


def two_machines(rng, tmp_path):
    """alpha: every claim holds. beta: 1 fails (one point), 2 fails (test 7 kinked),
    3 not measured (no GPU rate), 4 fails, 5 not measured (half measured), 6 fails."""
    mach = machine()
    alpha = thesis(rng, mach=mach) + [ramp(rng, "cpu", mach=mach), ramp(rng, "cuda", mach=mach)]
    median = statistics.median(p["speedup"] for p in report.speedups(alpha))
    mach["gpus"][0]["fp32_gflops"] = mach["cpu"]["fp32_gflops"] * median / rng.uniform(0.8, 1.2)
    frame = rng.uniform(5, 20, len(BLOCKS))
    frame[BLOCKS.index([32, 32])] = frame.min() * 0.95
    alpha += gpu_tuning(frame, mach=mach) + cpu_tuning(cpu_times(rng), mach=mach)
    alpha += constant("cuda", rng.uniform(1.1, 2, 3), rng, mach=mach)
    alpha += constant("cpu", rng.uniform(0.5, 2, 3), rng, mach=mach)

    kw = {"label": "beta", "mach": machine(gpu_gflops=None)}
    beta = thesis(rng, **kw) + [ramp(rng, "cpu", kink=True, **kw)]
    beta[1]["frame_ms"] = ms(2 * beta[0]["frame_ms"]["median"])  # the GPU slower at one point (a whole summary)
    frame[BLOCKS.index([32, 32])] = np.delete(frame, BLOCKS.index([32, 32])).min() * 1.1
    times = cpu_times(rng)
    del times["one per row"]
    beta += gpu_tuning(frame, **kw) + cpu_tuning(times, **kw) + constant("cuda", [1.5, 1.0, 1.5], rng, **kw)
    return write(tmp_path / "alpha.jsonl", alpha), write(tmp_path / "beta.jsonl", beta)


def test_write_report_end_to_end(tmp_path, rng):
    """Two machines in one report, beta's file cut short at its end (a run
    interrupted mid-write): a warning, a note, and everything else intact."""
    paths = two_machines(rng, tmp_path)
    with open(paths[1], "a") as f:
        f.write('{"format": "raybench-results", "vers')
    out = tmp_path / "rep"
    with pytest.warns(UserWarning, match="cut short"):
        path = report.write_report(list(paths), out)
    assert path == out / "report.md" and path.is_file()
    text = path.read_text(encoding="utf-8")
    lines = text.splitlines()
    header = next(line for line in lines if line.startswith("| # |"))
    assert header.endswith(f"| {A} | {B} |")  # the two machines side by side
    expected = [
        (HOLDS, FAILS),
        (HOLDS, FAILS),
        (HOLDS, NOT_MEASURED),
        (HOLDS, FAILS),
        (HOLDS, NOT_MEASURED),
        (HOLDS, FAILS),
    ]
    for number, want in enumerate(expected, 1):
        row = next(line for line in lines if line.startswith(f"| {number} |"))
        got = tuple(re.findall(r"\*\*(holds|does not hold|not measured)\*\*", row))
        assert got == want, (number, row)
    assert f"## {A}" in lines and f"## {B}" in lines
    assert all(str(p) in text for p in paths) and "## Notes" in text and "cut short" in text
    # Every plot referenced exists and is a PNG; nothing else is in the folder (no temporary files).
    pngs = re.findall(r"!\[[^\]]*\]\(([^)]+)\)", text)
    assert len(pngs) == 12 and len(set(pngs)) == 12  # 6 plots per machine, none overwritten
    for name in pngs:
        with Image.open(out / name) as im:
            assert im.format == "PNG" and im.width > 100
            im.verify()
    assert sorted(p.name for p in out.iterdir()) == sorted(pngs + ["report.html", "report.md"])


def test_zero_time_is_an_error_line_or_a_verdict_not_a_traceback(tmp_path, rng):
    frame, kernel = rng.uniform(5, 20, len(BLOCKS)), rng.uniform(1, 4, len(BLOCKS))
    kernel[0] = 0.0  # 2x2 "took no time", e.g. a hand-edited file
    path = write(tmp_path / "zero.jsonl", gpu_tuning(frame, kernel))
    try:
        report.write_report([path], tmp_path / "rep")
    except RaybenchError as exc:
        assert "\n" not in str(exc)
    else:
        row = next(
            line for line in (tmp_path / "rep" / "report.md").read_text().splitlines() if line.startswith("| 4 |")
        )
        assert f"**{FAILS}**" in row


# --- the command line (test_bench.py covers not-JSON and a missing file) ---------------------


def test_cli_report_bad_record_writes_nothing(tmp_path, rng, capsys):
    good = write(tmp_path / "good.jsonl", thesis(rng))
    r = ramp(rng)
    del r["frame_ms"]
    bad = write(tmp_path / "bad.jsonl", [r])
    (tmp_path / "rep").mkdir()
    code = run(["report", str(good), str(bad), "-o", str(tmp_path / "rep")])
    err = capsys.readouterr().err
    assert code == 2 and err.count("\n") == 1 and "bad.jsonl" in err and "frame_ms" in err, err
    assert "Traceback" not in err and list((tmp_path / "rep").iterdir()) == []


def test_each_kernel_is_judged_in_its_own_column(rng):
    """One machine measured with both kernels: two columns, each with its own
    speedups, never a fast CPU point matched with a simple GPU one."""
    simple = thesis(rng)
    fast = [dict(r, options={"kernel": "fast"}, frame_ms=ms(r["frame_ms"]["median"] / 3)) for r in thesis(rng)]
    columns = report.group(simple + fast)
    assert list(columns) == ["alpha, simple kernel", "alpha, fast kernel"]
    for name, records in columns.items():
        expected = {
            (r["width"], r["height"], r["spheres"]): r["frame_ms"]["median"] for r in records if r["device"] == "cpu"
        }
        for p in report.speedups(records):
            key = (p["width"], p["height"], p["spheres"])
            assert p["cpu_ms"] == expected[key], name


# --- the scaling suite and the BVH column ---------------------------------------


def scaling(rng, cap_at=3000):
    """Brute force linear in the count up to cap_at, then skipped; the BVH
    logarithmic; both devices."""
    out = []
    for device in ("cpu", "cuda"):
        a, b = rng.uniform(1e-3, 1e-1), rng.uniform(0.5, 5)
        for n in (10, 100, 1000, 10000, 100000, 1000000):
            if n <= cap_at:
                out.append(
                    rec(
                        "scaling",
                        device,
                        n,
                        a * n + 1,
                        size=(1680, 1050),
                        options={"kernel": "fast", "accel": "none", "cap_s": 1.0},
                    )
                )
            else:
                r = rec(
                    "scaling",
                    device,
                    n,
                    1,
                    size=(1680, 1050),
                    options={"kernel": "fast", "accel": "none", "cap_s": 1.0},
                )
                for key in ("frame_ms", "kernel_ms"):
                    del r[key]
                out.append(
                    {**r, "skipped": f"predicted {a * n / 1e3:.3g} s a frame, over the 1 s cap", "predicted_ms": a * n}
                )
            bvh = rec("scaling", device, n, b * np.log10(n), size=(1680, 1050), options={"accel": "bvh"})
            out.append({**bvh, "build_s": n * 1e-6, "rays_per_s": 1680 * 1050 / (b * np.log10(n) / 1e3)})
    return out


def test_scaling_series_keeps_skipped_points(rng):
    series = report.scaling_series(scaling(rng))
    assert {(s["device"], s["way"]) for s in series} == {
        (d, w) for d in ("cpu", "cuda") for w in ("BVH", "brute force, fast kernel")
    }
    for s in series:
        assert [p["spheres"] for p in s["points"]] == [10, 100, 1000, 10000, 100000, 1000000]
        skipped = [p["spheres"] for p in s["points"] if p["skipped"]]
        assert skipped == ([10000, 100000, 1000000] if s["accel"] == "none" else [])
        assert all((p["build_s"] is not None) == (s["accel"] == "bvh") for p in s["points"] if not p["skipped"])


def test_scaling_layouts_are_series_of_their_own(rng, tmp_path):
    """The denser scenes' points (options "layout") form their own series,
    named for the layout, beside the even spread's, in the table too."""
    layouts = [
        {**r, "options": {**r["options"], "layout": lay}}
        for lay in ("dense", "deep")
        for r in scaling(rng)
        if r["options"]["accel"] == "bvh"
    ]
    series = report.scaling_series(scaling(rng) + layouts)
    ways = {(s["device"], s["way"]) for s in series}
    assert {(d, f"BVH, {lay} scene") for d in ("cpu", "cuda") for lay in ("dense", "deep")} <= ways
    assert len(series) == 8 and all(len(s["points"]) == 6 for s in series)
    path = tmp_path / "r.jsonl"
    with ResultsWriter(path) as w:
        for r in scaling(rng) + layouts:
            w.write(r)
    assert "BVH, clusters scene" not in (text := report.write_report([path], tmp_path / "rep").read_text())
    assert "BVH, deep scene" in text


def test_bvh_records_get_their_own_column(rng):
    recs = thesis(rng) + [{**r, "options": {**r["options"], "accel": "bvh"}} for r in thesis(rng)]
    assert set(report.group(recs)) == {A, "alpha, BVH"}


def test_report_with_scaling_section(tmp_path, rng):
    path = tmp_path / "r.jsonl"
    with ResultsWriter(path) as w:
        for r in thesis(rng) + scaling(rng):
            w.write(r)
    text = report.write_report([path], tmp_path / "rep").read_text()
    section = text[text.index("## Beyond the thesis") :]
    assert "skipped: predicted" in section and "| BVH |" in section
    assert (tmp_path / "rep" / "alpha-scaling.png").exists()


def test_wgpu_records_are_labelled_with_their_adapter_and_judge_nothing(tmp_path, rng):
    """wgpu series and workgroup shapes are shown with the adapter that ran them
    (a CPU driver must not pass for a GPU); the GPU claims stay cuda's."""
    adapter = {
        "name": "llvmpipe (LLVM 15.0.6, 256 bits)",
        "backend": "Vulkan",
        "type": "CPU",
        "workgroup": [16, 16],
        "timing": "timestamp-query",
    }
    slope = rng.uniform(1, 5)
    wgpu = [
        rec("thesis", "wgpu", n, slope * n, kernel=0.9 * slope * n, test=1, options={"adapter": "llvmpipe"})
        for n in COUNTS
    ]
    wgpu += [
        rec("tuning", "wgpu", 300, t, size=(640, 480), kernel=0.9 * t, options={"workgroup": w})
        for w, t in (([8, 8], 120.0), ([16, 16], 100.0), ([32, 32], 150.0))
    ]
    for r in wgpu:
        r["adapter"] = adapter
    records = thesis(rng) + wgpu
    path = write(tmp_path / "r.jsonl", records)
    text = report.write_report([path], tmp_path / "out").read_text()
    assert "**wgpu** (llvmpipe (LLVM 15.0.6, 256 bits) (Vulkan, CPU))" in text
    assert "wgpu workgroups, on llvmpipe (LLVM 15.0.6, 256 bits) (Vulkan, CPU):" in text
    row = next(line for line in text.splitlines() if line.startswith("| 32x32 | 150"))
    assert row.endswith("| 1.50x |"), row
    # wgpu here is far slower than the CPU: were it taken for the GPU, claim 1 would fail
    v = verdict(records, 1)
    assert v["verdict"] == HOLDS and v["values"]["n"] == len(SIZES) * len(COUNTS)


# --- the secondary suite: does the GPU's lead hold for secondary rays? -------------------

SEC_SIZES = [(800, 600), (1680, 1050)]
SEC_COUNTS = [1000, 10_000, 100_000]
WHITTED = {"shading": "whitted", "depth": 5, "shadow_samples": 4}


def sec_rec(device, way, size, n, shading, rays_per_s, rng, **kw):
    """One secondary-suite record as the runner writes it: the frame time from
    rays_per_s and the rays a frame casts (for Whitted, random counts by kind)."""
    options = {"accel": "bvh"} if way == "bvh" else {"kernel": "simple", "accel": "none", "cap_s": 30.0}
    pixels = size[0] * size[1]
    if shading == "thesis":
        r = rec(
            "secondary", device, n, pixels / rays_per_s * 1e3, size=size, options={**options, "shading": "thesis"}, **kw
        )
        return {**r, "rays_per_s": pixels / (r["frame_ms"]["median"] / 1e3)}
    rays = {
        "primary": pixels,
        "shadow": int(pixels * rng.uniform(3, 8)),
        "reflection": int(pixels * rng.uniform(0.5, 2)),
        "refraction": int(pixels * rng.uniform(0.5, 2)),
    }
    total = sum(rays.values())
    r = rec("secondary", device, n, total / rays_per_s * 1e3, size=size, options={**options, **WHITTED}, **kw)
    median_s = r["frame_ms"]["median"] / 1e3
    return {**r, "rays": rays, "rays_per_frame": total, "rays_per_s": total / median_s, "kernel_rays_per_s": None}


def secondary(rng, kept, ways=("bvh", "none"), devices=("cpu", "cuda"), lead=(5.0, 50.0), **kw):
    """The secondary suite on one machine: at every way, size and count a
    thesis-shading twin and a Whitted record per device. The CPU's rays/s are
    random; the GPU leads on primary rays by a random factor in `lead`, and on
    secondary rays by that factor times kept(way) (a random share kept)."""
    out = []
    for way in ways:
        for size in SEC_SIZES:
            for n in SEC_COUNTS:
                cpu_primary = rng.uniform(1e6, 1e8)
                cpu_whitted = cpu_primary * rng.uniform(0.2, 1.0)
                primary_lead = rng.uniform(*lead)
                rates = {
                    "cpu": (cpu_primary, cpu_whitted),
                    "cuda": (cpu_primary * primary_lead, cpu_whitted * primary_lead * kept(way)),
                    "wgpu": (cpu_primary * 2, cpu_whitted * 0.1),
                }
                for device in devices:
                    p, s = rates[device]
                    out.append(sec_rec(device, way, size, n, "thesis", p, rng, **kw))
                    out.append(sec_rec(device, way, size, n, "whitted", s, rng, **kw))
    return out


def ref_leads(records):
    """The GPU's lead per matched point from the records' frame times and ray
    counts, computed here without the report: (secondary lead, primary lead)."""
    at = {}
    for r in records:
        if "skipped" in r:
            continue
        rays = r["rays_per_frame"] if r["options"]["shading"] == "whitted" else r["width"] * r["height"]
        key = (r["options"]["accel"], r["width"], r["height"], r["spheres"], r["options"]["shading"])
        at.setdefault(key, {})[r["device"]] = rays / r["frame_ms"]["median"]
    out = {}
    for (accel, w, h, n, shading), by in at.items():
        if "cpu" in by and "cuda" in by:
            out.setdefault((accel, w, h, n), {})[shading] = by["cuda"] / by["cpu"]
    return {k: (v["whitted"], v["thesis"]) for k, v in out.items() if len(v) == 2}


def test_secondary_leads_are_matched_rays_per_second(rng):
    """Leads pair the CPU and the GPU at the same way, size and count, the
    Whitted frames and their twins apart; a point skipped or missing on
    either device, or measured with one shading only, is left out."""
    records = secondary(rng, lambda way: rng.uniform(0.1, 2))
    drop = [r for r in records if r["device"] == "cpu" and r["options"]["accel"] == "none"]
    skipped = drop[-1]  # the CPU's brute force at the largest point: skipped
    for key in ("frame_ms", "kernel_ms", "rays", "rays_per_frame", "rays_per_s", "kernel_rays_per_s"):
        skipped.pop(key)
    skipped.update(skipped="predicted 9e+03 s a frame, over the 30 s cap", predicted_ms=9e6)
    records.remove(drop[0])  # a twin never measured (an interrupted run)
    records.append(sec_rec("cuda", "bvh", (640, 480), 1000, "whitted", 1e9, rng))  # no CPU point
    leads = report.secondary_leads(records)
    expected = ref_leads(records)
    assert len(leads) == len(expected) == 2 * len(SEC_SIZES) * len(SEC_COUNTS) - 2
    for p in leads:
        secondary_lead, primary_lead = expected[(p["accel"], p["width"], p["height"], p["spheres"])]
        assert p["secondary"] == pytest.approx(secondary_lead) and p["primary"] == pytest.approx(primary_lead)
        assert p["kept"] == pytest.approx(secondary_lead / primary_lead)
    points = report.secondary_points(records)
    gone = next(p for p in points if p["device"] == "cpu" and p["accel"] == "none" and p["spheres"] == 100_000
                and p["width"] == 1680)  # fmt: skip
    assert gone["whitted"]["skipped"].startswith("predicted") and gone["primary"]["skipped"] is None


@pytest.mark.parametrize(
    "kept,expected",
    [(0.5, HOLDS), ("above", HOLDS), (0.49, FAILS), ("below", FAILS), ("gpu slower", FAILS), ("one way", FAILS)],
)
def test_secondary_verdict_both_ways(rng, kept, expected):
    """The rule: per way, the median share of the primary-ray lead kept on
    secondary rays at least 0.5, and the GPU still faster; every way must
    hold. The shares are set per point around the threshold, the median
    exactly where the parameter says."""
    lead = (5.0, 50.0)
    if kept == "above":
        share = {"bvh": rng.uniform(0.5, 3), "none": rng.uniform(0.5, 3)}
    elif kept == "below":
        share = {"bvh": rng.uniform(0.05, 0.49), "none": rng.uniform(0.05, 0.49)}
    elif kept == "gpu slower":  # keeps 80% of a lead that was small: slower than the CPU on secondary rays
        share, lead = {"bvh": 0.8, "none": 0.8}, (1.01, 1.2)
    elif kept == "one way":
        share = {"bvh": rng.uniform(0.05, 0.45), "none": rng.uniform(0.55, 3)}
    else:
        share = {"bvh": kept, "none": kept}
    records = secondary(rng, lambda way: share[way], lead=lead)
    v = report.secondary_verdict(records)
    assert v["verdict"] == expected, v["measured"]
    n = len(SEC_SIZES) * len(SEC_COUNTS)
    for way, accel in (("BVH", "bvh"), ("brute force, simple kernel", "none")):
        got = v["ways"][way]
        assert got["n"] == n and got["kept"] == pytest.approx(share[accel])
        mine = [ref for key, ref in ref_leads(records).items() if key[0] == accel]
        assert got["lead"] == pytest.approx(statistics.median(s for s, _ in mine))
        assert got["verdict"] == (HOLDS if share[accel] >= 0.5 and got["lead"] > 1 else FAILS)
    if kept == "one way":
        assert v["ways"]["BVH"]["verdict"] == FAILS and v["ways"]["brute force, simple kernel"]["verdict"] == HOLDS


@pytest.mark.parametrize("devices", [("cpu",), ("cuda",), ("cpu", "wgpu")])
def test_secondary_verdict_cannot_be_decided_on_one_device(rng, devices):
    """One device (or the CPU and wgpu, which decides nothing): no verdict."""
    v = report.secondary_verdict(secondary(rng, lambda way: 1.0, devices=devices))
    assert v["verdict"] == NOT_MEASURED and "cannot be decided" in v["measured"] and v["points"] == []


def test_report_secondary_section(tmp_path, rng):
    """Two machines with cpu and cuda secondary records: on alpha the GPU
    keeps its lead, on beta it does not; each section gives its verdict, the
    rule, both charts, the rays by kind and the leads; the thesis's claims
    table does not count secondary records. A CPU-only machine: cannot be
    decided."""
    alpha = secondary(rng, lambda way: rng.uniform(0.6, 2.0)) + thesis(rng)
    beta = secondary(rng, lambda way: rng.uniform(0.05, 0.4), label="beta")
    gamma = secondary(rng, lambda way: 1.0, devices=("cpu",), label="gamma")
    path = write(tmp_path / "r.jsonl", alpha + beta + gamma)
    text = report.write_report([path], tmp_path / "rep").read_text()
    section = text[text.index("## Beyond the thesis: secondary rays") :]
    parts = {label: section[section.index(f"### {label}: secondary rays") :] for label in ("alpha", "beta", "gamma")}
    question = f"**{report.SECONDARY_QUESTION}**"
    assert parts["alpha"].split("\n\n")[2].startswith(f"{question} **{HOLDS}**: BVH: the GPU leads by")
    assert f"{question} **{FAILS}**" in parts["beta"].split("### gamma")[0]
    assert f"{question} **{NOT_MEASURED}**: cannot be decided" in parts["gamma"]
    assert section.count(report.SECONDARY_RULE) == 3 and "at least 0.5" in report.SECONDARY_RULE
    assert "**gamma**: CPU Synthetic CPU" in parts["gamma"]  # described here: it has no other section
    for slug in ("alpha-secondary", "beta-secondary", "gamma-secondary"):
        for chart in ("rays", "frames"):
            with Image.open(tmp_path / "rep" / f"{slug}-{chart}.png") as im:
                assert im.format == "PNG" and im.width > 100
    r = next(r for r in beta if r["device"] == "cuda" and r["options"]["shading"] == "whitted")
    row = next(line for line in parts["beta"].splitlines() if line.startswith(f"| GPU | BVH | {r['width']}x"))
    assert f"| {r['rays']['shadow']:,} | {r['rays']['reflection']:,} | {r['rays']['refraction']:,} |" in row
    leads = parts["alpha"][parts["alpha"].index("The GPU's lead at each point") :].split("### beta")[0]
    assert (
        leads.count("\n| BVH |") == leads.count("\n| brute force, simple kernel |") == len(SEC_SIZES) * len(SEC_COUNTS)
    )
    claims = next(line for line in text.splitlines() if line.startswith("| # |"))
    assert claims.endswith(f"| {A} |")  # beta and gamma ran no thesis suite: no column of not measured


OLD_RESULTS = [
    "benchmarks/results/h100/results-20261122-234729.jsonl",
    "benchmarks/results/h200/kernels/thesis-20261129-d.jsonl",
    "benchmarks/results/epyc-2c-lavapipe/results-20261123-030724.jsonl",
    "benchmarks/results/epyc-2c-cpu-only/bvh-walk/scaling-20261123.jsonl",
]


def test_old_results_files_still_report(tmp_path):
    """Results files committed before the secondary suite load and report as
    before: every record the thesis's shading, no secondary section."""
    from pathlib import Path

    root = Path(__file__).resolve().parent.parent
    paths = [root / p for p in OLD_RESULTS]
    machines, _ = report.load(paths)
    records = [r for rs in machines.values() for r in rs]
    assert len(records) > 100 and {report.shading_of(r) for r in records} == {"thesis"}
    assert report.secondary_points(records) == []
    text = report.write_report(paths, tmp_path / "rep").read_text()
    assert "## The thesis's claims" in text and "secondary rays" not in text


@pytest.mark.parametrize("bvh_kept,expected", [(0.8, HOLDS), (0.3, FAILS)])
def test_secondary_way_without_a_matched_point_is_left_out(rng, bvh_kept, expected):
    """Brute force measured on the CPU alone (the GPU's skipped, say): the BVH's points decide."""
    records = [
        r
        for r in secondary(rng, lambda way: bvh_kept if way == "bvh" else 0.01)
        if not (r["device"] == "cuda" and r["options"]["accel"] == "none")
    ]
    v = report.secondary_verdict(records)
    assert list(v["ways"]) == ["BVH"] and v["verdict"] == expected


def test_report_with_dynamic_section(tmp_path, rng):
    """The dynamic suite's table: frames/s from the median frame, the update's
    ms and share, refits and builds, one row per device and build."""
    records = []
    for build, frame_ms in (("host", 40.0), ("gpu", 10.0)):
        r = rec("dynamic", "cuda", 100_000, frame_ms, size=(1680, 1050), kernel=2.0)
        r["options"] = {"accel": "bvh", "motion": "orbits", "build": build}
        r["update_ms"] = {k: frame_ms / 4 for k in ("mean", "median", "p5", "p95", "min", "max")}
        r["updates"] = {"refit": 9, "build": 1} if build == "gpu" else {"build": 10}
        r["update_share"] = 0.25
        records.append(r)
    path = write(tmp_path / "r.jsonl", thesis(rng) + records)
    text = report.write_report([path], tmp_path / "rep").read_text()
    section = text[text.index("## Beyond the thesis: spheres that move") :]
    assert (
        "| GPU | gpu | 1680x1050 | 100,000 | 100 |" in section
        and "| GPU | host | 1680x1050 | 100,000 | 25.0 | 40.0 |" in section
    )
    assert "| 25% | 9 / 1 |" in section and "| 0 / 10 |" in section


def part(quantity, median, label="alpha", **fields):
    """A record of the parts suite (results.PART): a quantity timed apart from any frame."""
    return {
        "suite": "parts",
        "quantity": quantity,
        "device": "cpu",
        "time_ms": ms(median),
        "run": {"id": f"{label}-{DATE}", "date": DATE, "label": label, "machine": machine()},
        **fields,
    }


def test_report_with_parts_section(tmp_path, rng):
    """What the benchmark scripts time apart from frames (a build, a start-up) has a table of its
    own, read beside a suite's records and alone; each needs a quantity and a time."""
    parts = [
        part("bvh-build", 41.0, spheres=100_000, options={"threads": 2}, samples=5, values={"depth": 19}),
        part("startup-warm", 812.0, width=320, height=200, spheres=1000, values={"sah_over_host": None}),
    ]
    path = write(tmp_path / "r.jsonl", thesis(rng) + parts)
    text = report.write_report([path], tmp_path / "rep").read_text()
    section = text[text.index("## Beyond the thesis: parts timed apart") : text.index("## Sources")]
    assert "| bvh-build | CPU | 100,000 | – | threads 2 | 41.0 | 36.9-45.1 | 5 | depth 19 |" in section
    assert "| startup-warm | CPU | 1,000 | 320x200 | – | 812 |" in section and "sah_over_host –" in section
    alone = write(tmp_path / "parts.jsonl", parts)
    assert "## Beyond the thesis: parts timed apart" in report.write_report([alone], tmp_path / "rep2").read_text()
    for broken in ({"time_ms": None}, {"quantity": "a build"}, {"values": {"depth": "deep"}}):
        bad = write(tmp_path / "bad.jsonl", [{**parts[0], **broken}])
        with pytest.raises(RaybenchError):
            report.write_report([bad], tmp_path / "rep3")


def test_scaling_ways_name_a_chosen_tree_width_and_a_tree_built_on_the_gpu():
    from raybench.bench.report.series import way_of

    bvh = {"accel": "bvh"}
    assert way_of({"options": bvh}) == "BVH" and way_of({"options": {**bvh, "build": "host"}}) == "BVH"
    assert way_of({"options": {**bvh, "tree_width": 4}}) == "BVH, 4-wide tree"
    assert way_of({"options": {**bvh, "build": "gpu"}}) == "BVH, built on the GPU"
    gpu_tree = {**bvh, "build": "gpu", "quality": "treelet", "walk": "packet"}
    assert way_of({"options": gpu_tree}) == "BVH, built on the GPU (treelet), packet walk"
    assert way_of({"options": {"accel": "none", "kernel": "fast"}}) == "brute force, fast kernel"


def test_multi_gpu_deliveries_are_series_of_their_own():
    from raybench.bench.report.series import multi_gpu_series

    records = []
    for delivery, fps in (("shared", 40.0), ("sent", 20.0)):
        for workers in (1, 2):
            r = rec("multi-gpu", "cuda", 1000, 1e3 / (fps * workers), size=(8192, 8192))
            r["options"] = {"workers": workers, "job": "frame", "delivery": delivery}
            records.append(r)
    series = multi_gpu_series(records)
    assert [s["delivery"] for s in series] == ["shared", "sent"] or [s["delivery"] for s in series] == [
        "sent",
        "shared",
    ]
    assert all(len(s["points"]) == 2 and s["points"][1]["speedup"] == pytest.approx(2.0) for s in series)
