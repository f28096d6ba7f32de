"""What a new user meets in the first minutes: ./run.sh's arguments (the default main job at 2 s
a point, --full one flag away), progress as plain lines when the output is not a terminal, the
headline's interval and the loaded-machine warning, and Whitted shading that says what it lacks.
The end-to-end run (lines in a real bench, the interval printed) is test_bench's quick run."""

import os
import subprocess
import threading
import time
from pathlib import Path

import numpy as np
import pytest

import raybench
from raybench.bench import headline, load, progress
from raybench.bench.suites import Point
from raybench.cli.options import shading_notes

ROOT = Path(__file__).resolve().parent.parent


# --- ./run.sh -------------------------------------------------------------------------


@pytest.fixture
def fake_checkout(tmp_path):
    """run.sh in a folder whose .venv's python and raybench only print their arguments."""
    (tmp_path / "run.sh").write_text((ROOT / "run.sh").read_text())
    bin_ = tmp_path / ".venv" / "bin"
    bin_.mkdir(parents=True)
    for name in ("python", "raybench"):
        (bin_ / name).write_text(f'#!/bin/sh\necho "{name} $*"\n')
        (bin_ / name).chmod(0o755)
    return tmp_path


@pytest.mark.parametrize(
    "args, bench",
    [
        ([], "raybench bench --duration 2"),
        (["--full"], "raybench bench"),
        (["--full", "--suite", "all"], "raybench bench --suite all"),
        (["--quick"], "raybench bench --quick"),
        (["--duration", "5", "--device", "cpu"], "raybench bench --duration 5 --device cpu"),
        (["--suite", "secondary"], "raybench bench --duration 2 --suite secondary"),
    ],
)
def test_run_sh_is_the_short_job_and_full_is_one_flag_away(fake_checkout, args, bench):
    done = subprocess.run(["bash", "run.sh", *args], cwd=fake_checkout, capture_output=True, text=True, check=True)
    lines = done.stdout.splitlines()
    assert lines[-2:] == ["raybench info", bench]
    assert "setting up .venv" not in done.stdout  # there already: no first-run line


# --- progress as lines ---------------------------------------------------------------


class Clock:
    def __init__(self):
        self.t = 100.0

    def __call__(self):
        return self.t


def _points():
    thesis = [Point("thesis", "cpu", 800, 600, n, {"accel": "none"}, test=4) for n in (100, 500)]
    return [*thesis, Point("test7", "cpu", 800, 600, 30, {"accel": "none"}, test=7, ramp=(10, 20, 30))]


def test_a_line_per_suite_and_point_with_what_is_left():
    said, clock = [], Clock()
    points = _points()
    lines = progress.Lines(said.append, points, [3.0, 3.0, 6.0], now=clock)
    try:
        lines.point(0, points[0])
        clock.t += 6.0  # the first point took twice its nominal 3 s (a compile): the rest at that pace
        lines.done(0)
        lines.point(1, points[1])
        lines.done(1)
        clock.t += 6.0
        lines.point(2, points[2])
    finally:
        lines.close()
    assert said == [
        "suite thesis: 2 points",
        "[1/3] thesis test 4 cpu 800x600 100 spheres accel=none  (0:00 so far, about 0:12 left)",
        "[2/3] thesis test 4 cpu 800x600 500 spheres accel=none  (0:06 so far, about 0:18 left)",
        "suite test7: 1 point",
        "[3/3] test7 cpu 800x600 test 7 ramp 10..30 accel=none  (0:12 so far, about 0:12 left)",
    ]


def test_a_long_point_is_never_silent(monkeypatch):
    monkeypatch.setattr(progress, "HEARTBEAT_S", 0.0)
    said, seen = [], threading.Event()

    def echo(line):
        said.append(line)
        if line.startswith("  still on"):
            seen.set()

    points = _points()
    lines = progress.Lines(echo, points, [1.0, 1.0, 1.0])
    try:
        lines.point(0, points[0])
        assert seen.wait(10), said
    finally:
        lines.close()
    assert said[2].startswith("  still on thesis test 4 cpu 800x600 100 spheres accel=none: 0:0")


def test_clock():
    assert [progress.clock(s) for s in (0, 59.4, 61, 3600)] == ["0:00", "0:59", "1:01", "60:00"]


# --- the headline's interval, and a loaded machine -------------------------------------


def _records(samples: dict[int, list[float]]) -> list[dict]:
    run = {"label": "here", "settings": {"seed": 0}, "machine": {"cpu": {"model": "a CPU", "physical_cores": 2}}}
    return [
        {
            "suite": "thesis",
            "device": "cpu",
            "width": 800,
            "height": 600,
            "spheres": n,
            "options": {"kernel": "fast", "accel": "none"},
            "frame_ms": {"median": float(np.median(s))},
            "samples_ms": s,
            "run": run,
        }
        for n, s in samples.items()
    ]


def test_the_interval_of_steady_frames_is_the_headline_itself():
    records = _records({100: [10.0] * 50, 500: [40.0] * 50, 1000: [80.0] * 50})
    # by hand: 480,000 rays at 10, 40 and 80 ms, in millions a second, geometric mean
    expected = (48.0 * 12.0 * 6.0) ** (1 / 3)
    assert headline.score(records, "cpu") == pytest.approx(expected)
    low, high = headline.interval(records, "cpu")
    assert low == pytest.approx(expected) and high == pytest.approx(expected)


def test_the_interval_holds_the_headline_and_widens_with_noise():
    rng = np.random.default_rng(1)
    base = {100: 10.0, 500: 40.0, 1000: 80.0}
    widths = []
    for noise in (0.02, 0.2):
        records = _records({n: list(ms * (1 + noise * rng.standard_normal(200))) for n, ms in base.items()})
        low, high = headline.interval(records, "cpu")
        assert low < headline.score(records, "cpu") < high
        widths.append((high - low) / headline.score(records, "cpu"))
    assert widths[1] > 4 * widths[0]


def test_no_interval_without_kept_frames():
    records = _records({100: [10.0] * 50, 500: [40.0] * 50, 1000: [80.0] * 2})
    assert headline.interval(records, "cpu") is None


def test_a_loose_interval_is_flagged_in_the_summary():
    # half of each point's frames slowed by a half (a neighbour's burst of work): the median is
    # either, depending on which stretch the resampled blocks come from
    base = {100: 10.0, 500: 40.0, 1000: 80.0}
    noisy = _records({n: [ms] * 50 + [1.5 * ms] * 50 for n, ms in base.items()})
    out = headline.summary(noisy, [])
    assert "95% interval" in out[1] and out[2].startswith("  warning: the interval of")
    steady = headline.summary(_records({100: [10.0] * 50, 500: [40.0] * 50, 1000: [80.0] * 50}), [])
    assert not any("warning" in line for line in steady)


def test_the_interval_holds_the_true_headline_within_a_run():
    """What the interval claims: frames drawn independently about known medians (a quiet run),
    the 95% interval holds the headline those medians give, worked by hand, in about 95% of runs."""
    rng = np.random.default_rng(7)
    true = {100: 10.0, 500: 40.0, 1000: 80.0}
    expected = float(np.prod([0.48 / (ms / 1e3) for ms in true.values()]) ** (1 / 3))
    held = 0
    for _ in range(60):
        low, high = headline.interval(
            _records({n: list(ms * (1 + 0.05 * rng.standard_normal(60))) for n, ms in true.items()}), "cpu", rounds=500
        )
        held += low <= expected <= high
    assert 51 <= held <= 60  # 95% of 60 is 57; a binomial's 99.9% band reaches down to 51


def test_an_interval_is_of_its_own_run_and_the_summary_says_so():
    """Two runs of one machine, the second under a neighbour's load through all of it (every
    frame 1.5 times as long, as the EPYC's second back-to-back run was 3.4 times): each interval
    holds its own headline and not the other's, which no resampling of one run's frames can
    mend, so the summary says what the interval covers and points to the page that explains it."""
    rng = np.random.default_rng(3)
    base = {100: 10.0, 500: 40.0, 1000: 80.0}
    quiet = _records({n: list(ms * (1 + 0.02 * rng.standard_normal(60))) for n, ms in base.items()})
    loaded = _records({n: list(1.5 * ms * (1 + 0.02 * rng.standard_normal(60))) for n, ms in base.items()})
    (ql, qh), (ll, lh) = headline.interval(quiet, "cpu"), headline.interval(loaded, "cpu")
    assert ql <= headline.score(quiet, "cpu") <= qh and ll <= headline.score(loaded, "cpu") <= lh
    assert not ql <= headline.score(loaded, "cpu") <= qh and not ll <= headline.score(quiet, "cpu") <= lh
    for lines in (headline.summary(quiet, []), headline.summary(loaded, [])):
        (note,) = [x for x in lines if headline.SPANS_FRAMES in x]  # no repeats: one pass's frames
        assert note.endswith(f"({headline.PAGE})")
    page = (ROOT / "docs" / "thesis.md").read_text()
    assert "\n## The headline's interval\n" in page and headline.PAGE.endswith("#the-headlines-interval")
    # no interval (frames not kept): nothing to qualify
    few = _records({100: [10.0] * 2, 500: [40.0] * 2, 1000: [80.0] * 2})
    assert not any("frames only" in x or "passes" in x for x in headline.summary(few, []))


def _passes_of(rng, true: dict, drift: float, noise: float, passes: int) -> list[dict]:
    """One run's records whose headline points were timed in `passes` passes, each pass's frames
    scaled by a drift of its own (a clock or a neighbour that held through the pass), as bench
    writes them and results.read folds them (repeats)."""
    scale = 1 + drift * rng.standard_normal(passes)
    frames = {
        n: [list(ms * scale[k] * (1 + noise * rng.standard_normal(40))) for k in range(passes)]
        for n, ms in true.items()
    }
    records = _records({n: f[0] for n, f in frames.items()})
    for r in records:
        r["repeats"] = [
            {"frame_ms": {"median": float(np.median(f))}, "samples_ms": f} for f in frames[r["spheres"]][1:]
        ]
    return records


def test_the_interval_holds_a_drift_between_passes():
    """A machine that drifts over minutes by 1% while each pass's frames vary by 0.5%: the
    interval made from three passes holds the true headline (that of the undrifted medians) in
    about 95% of runs, as Student's t promises, where the frames alone, one pass or all pooled,
    hold it far less often: the repeats are what the interval needs, not decoration."""
    rng = np.random.default_rng(11)
    true = {100: 10.0, 500: 40.0, 1000: 80.0}
    expected = float(np.prod([0.48 / (ms / 1e3) for ms in true.values()]) ** (1 / 3))
    held = pooled = 0
    for _ in range(80):
        records = _passes_of(rng, true, drift=0.01, noise=0.005, passes=3)
        assert headline.passes(records, "cpu") == 3
        low, high = headline.interval(records, "cpu", rounds=300)
        held += low <= expected <= high
        for r in records:
            r["samples_ms"] = [x for p in [r["samples_ms"]] + [q["samples_ms"] for q in r.pop("repeats")] for x in p]
        low, high = headline.interval(records, "cpu", rounds=300)  # the same frames, as one pass
        pooled += low <= expected <= high
    assert held >= 70  # 95% of 80 is 76; a binomial's 99.9% band reaches down to 70
    assert pooled <= 60


def test_the_summary_says_its_interval_spans_passes():
    rng = np.random.default_rng(5)
    records = _passes_of(rng, {100: 10.0, 500: 40.0, 1000: 80.0}, drift=0.002, noise=0.005, passes=3)
    low, high = headline.interval(records, "cpu")
    value = headline.score(records, "cpu")
    assert low <= value <= high
    (line,) = [x for x in headline.summary(records, []) if x.startswith("  this machine")]
    assert f"95% interval {low:.3g} to {high:.3g}" in line
    assert any(headline.SPANS in x for x in headline.summary(records, []))


def test_other_processes_share_of_the_machine(monkeypatch):
    """Other processes' share: the machine's busy time less this process tree's, over wall time
    and cores (psutil's readings replaced by made-up ones, worked by hand)."""
    from types import SimpleNamespace

    readings = {"wall": 10.0, "busy": 100.0, "own": 5.0}
    monkeypatch.setattr(load.time, "monotonic", lambda: readings["wall"])
    monkeypatch.setattr(load, "_busy", lambda times: readings["busy"])
    monkeypatch.setattr(load, "_own", lambda process: readings["own"])
    monkeypatch.setattr(load.psutil, "cpu_count", lambda: 2)
    monkeypatch.setattr(load.psutil, "cpu_times", lambda: SimpleNamespace())
    watch = load.Load()
    # 20 s of wall on 2 cores = 40 core-seconds; the machine was busy 30 of them, 18 of them ours
    readings.update(wall=30.0, busy=130.0, own=23.0)
    assert watch.others() == pytest.approx(12 / 40)
    readings.update(own=40.0)  # ours more than the machine's (readings at different instants): none
    assert watch.others() == 0.0
    assert load.warning(0.05) is None and load.warning(load.LOADED) is None
    assert "other processes took 30% of its CPU time" in load.warning(0.3)


def test_a_real_reading_is_a_share():
    watch = load.Load()
    time.sleep(0.2)
    assert 0.0 <= watch.others() <= 1.0


# --- Whitted shading says what it lacks ------------------------------------------------


def _shaded(depth=None, samples=None):
    return {"shading": "whitted", "depth": depth, "shadow_samples": samples}


def test_whitted_without_lights_says_so_and_what_it_drew():
    plain = raybench.random_spheres(20)
    (note,) = shading_notes(plain, _shaded())
    assert "no lights" in note and "the thesis's picture" in note and "--materials" in note
    assert shading_notes(plain, {"shading": "thesis", "depth": None, "shadow_samples": None}) == []
    idle = shading_notes(plain, _shaded(depth=3, samples=2))
    assert idle[1] == "note: --depth has no effect: the scene has no mirrors or glass to bounce from"
    assert idle[2].startswith("note: --shadow-samples has no effect")


def test_whitted_with_lights_and_materials_has_nothing_to_say():
    assert shading_notes(raybench.random_spheres(20, materials=True), _shaded(depth=3, samples=2)) == []


def test_whitted_with_lights_but_only_matte_spheres_says_there_are_no_bounces():
    scene = raybench.random_spheres(5)
    lit = raybench.Scene(scene.centers, scene.radii, scene.colors, lights=[raybench.Light(position=(0, 5, 0))])
    notes = shading_notes(lit, _shaded(samples=4))
    assert "no sphere has a mirror or glass material" in notes[0]
    assert notes[1].startswith("note: --shadow-samples has no effect: the scene has no area light")


@pytest.mark.slow  # its first run compiles the CPU's Whitted kernels
def test_render_says_what_whitted_lacked_and_draws_what_it_said(capsys, tmp_path):
    from PIL import Image

    from raybench.cli import run

    out_png = tmp_path / "w.png"
    argv = ["render", "--spheres", "20", "--size", "24x16", "--device", "cpu", "--shading", "whitted", "-o"]
    assert run([*argv, str(out_png)]) == 0
    out, err = capsys.readouterr()
    assert err == "" and "note: --shading whitted: the scene has no lights" in out
    # what the note says it drew: the thesis's picture, bit for bit
    thesis = raybench.render(raybench.random_spheres(20), width=24, height=16, device="cpu").image
    assert np.array_equal(np.asarray(Image.open(out_png)), thesis)


@pytest.mark.parametrize(
    "settings, kernels_given, said",
    [
        ({"accels": ["bvh"], "devices": [], "kernels": ["simple"], "builds": []}, True, ["--kernel has no effect"]),
        ({"accels": ["none"], "devices": ["wgpu"], "kernels": ["fast"], "builds": []}, True, ["--kernel fast has no"]),
        ({"accels": ["none"], "devices": ["cuda"], "kernels": ["fast"], "builds": ["gpu"]}, False, ["--build has no"]),
        ({"accels": ["bvh", "none"], "devices": [], "kernels": ["fast"], "builds": ["gpu"]}, True, []),
    ],
)
def test_bench_says_which_options_change_nothing(settings, kernels_given, said):
    from raybench.cli.bench import idle_options

    notes = idle_options(settings, kernels_given)
    assert len(notes) == len(said) and all(n.startswith(f"note: {s}") for n, s in zip(notes, said))


def test_run_sh_first_install_prints_a_line_a_package(fake_checkout):
    """No .venv yet: run.sh says it is setting one up, and pip lists its packages as it goes
    rather than staying quiet for the minute or two a first install takes."""
    import shutil

    shutil.rmtree(fake_checkout / ".venv")
    stub = fake_checkout / "bin"
    stub.mkdir()
    # python3 -m venv .venv: a .venv whose programs print their arguments
    (stub / "python3").write_text(
        "#!/bin/sh\nmkdir -p .venv/bin\nfor n in python raybench; do\n"
        '  printf \'#!/bin/sh\\necho "%s $*"\\n\' "$n" > .venv/bin/$n; chmod +x .venv/bin/$n\ndone\n'
    )
    (stub / "python3").chmod(0o755)
    env = {**os.environ, "PATH": f"{stub}:{os.environ['PATH']}"}
    done = subprocess.run(["bash", "run.sh"], cwd=fake_checkout, capture_output=True, text=True, check=True, env=env)
    lines = done.stdout.splitlines()
    assert lines[0].startswith("setting up .venv: about 640 MiB")
    assert lines[1] == "python -m pip install --progress-bar off --disable-pip-version-check -e ."
    assert lines[-1] == "raybench bench --duration 2"


def test_the_headline_points_are_timed_again_later_in_the_run():
    """The thesis suite's plan: each device's headline points once where they fall, again in
    the middle of its points and at their end; no other point is repeated."""
    from raybench.bench import suites

    for quick in (True, False):
        plan = suites.points(["thesis"], ["cpu"], quick=quick, cores=2, accels=("bvh", "none"))
        counted = [
            (i, p)
            for i, p in enumerate(plan)
            if headline.counts_point(p.suite, p.device, (p.width, p.height), p.spheres, p.options)
        ]
        assert sorted((p.spheres, p.repeat) for _, p in counted) == sorted(
            (n, k) for n in headline.SPHERES for k in range(suites.HEADLINE_REPEATS + 1)
        )
        assert all(not p.repeat for p in plan if (p.width, p.height) != headline.SIZE or p.options["accel"] != "none")
        last = max(i for i, p in enumerate(plan) if p.suite == "thesis" and not p.repeat and p.device == "cpu")
        firsts = [i for i, p in counted if p.repeat == 0]
        middles = [i for i, p in counted if p.repeat == 1]
        ends = [i for i, p in counted if p.repeat == 2]
        assert max(firsts) < min(middles) < max(middles) < last < min(ends)
