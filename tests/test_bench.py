"""The benchmark: suite points, statistics, the results file under interruption,
and a --quick run end to end on the CPU."""

import os
import re
import signal
import subprocess
import sys
import time

import numpy as np
import pytest
from conftest import sigint_default

from raybench import RaybenchError, lighting
from raybench.bench import report, results, results_schema, runner, stats, suites
from raybench.bench.results import ResultsWriter
from raybench.cli import run


def test_thesis_points_cover_tests_1_to_7():
    pts = suites.points(["thesis"], ["cpu", "cuda"])
    thesis = [p for p in pts if p.suite == "thesis" and not p.repeat]
    assert len(thesis) == 2 * 3 * 10
    # and each device's three headline points timed twice more (its interval's passes)
    again = [(p.device, p.width, p.spheres, p.repeat) for p in pts if p.repeat]
    assert sorted(again) == sorted((d, 800, n, k) for d in ("cpu", "cuda") for n in (100, 500, 1000) for k in (1, 2))
    assert {p.test for p in thesis if p.device == "cuda"} == {1, 2, 3}
    assert {p.test for p in thesis if p.device == "cpu"} == {4, 5, 6}
    assert {(p.width, p.height) for p in thesis} == {(800, 600), (1280, 800), (1680, 1050)}
    assert sorted({p.spheres for p in thesis}) == list(range(100, 1001, 100))
    ramps = [p for p in pts if p.suite == "test7"]
    assert [p.device for p in ramps] == ["cpu", "cuda"]
    assert ramps[0].ramp == tuple(range(10, 1001, 10))


def test_tuning_points_follow_the_thesis():
    pts = suites.points(["tuning"], ["cpu", "cuda"], cores=4, kernels=("simple",))
    cpu = {p.options["label"]: p.options["threads"] for p in pts if p.device == "cpu"}
    assert cpu == {"1 thread": 1, "half the cores": 2, "all cores": 4, "2x cores": 8, "one per row": 1050}
    blocks = [tuple(p.options["block"]) for p in pts if p.device == "cuda"]
    assert {(2, 2), (4, 4), (8, 8), (16, 16), (32, 32)} <= set(blocks)
    assert any(x != y for x, y in blocks), "some non-square shapes"
    # The fast kernel launches at most 256 threads per block: larger shapes are left out.
    fast = [p.options["block"] for p in suites.points(["tuning"], ["cuda"], kernels=("fast",))]
    assert fast and all(x * y <= 256 for x, y in fast) and [16, 16] in fast
    # One core: half the cores and all cores are the same setting, measured once.
    assert [p.options["threads"] for p in suites.points(["tuning"], ["cpu"], cores=1)] == [1, 2, 1050]


def test_constant_vs_runtime_pairs():
    pts = suites.points(["constant-vs-runtime"], ["cpu"], kernels=("fast",))
    modes = {(p.spheres, p.options["count"]) for p in pts}
    assert modes == {(n, m) for n in suites.CONSTANT_COUNTS for m in ("constant", "runtime")}
    # only the simple kernel has a compile-time count, whatever kernels were asked for
    assert {p.options["kernel"] for p in pts} == {"simple"}


def test_kernels_multiply_the_thesis_and_tuning_suites():
    one = suites.points(["thesis", "tuning"], ["cpu"], cores=4)
    both = suites.points(["thesis", "tuning"], ["cpu"], cores=4, kernels=("fast", "simple"))
    assert {p.options["kernel"] for p in one} == {"fast"}
    firsts = [p for p in one if not p.repeat]
    assert len([p for p in both if not p.repeat]) == 2 * len(firsts)
    assert sorted(p.describe() for p in both if p.options["kernel"] == "simple") == sorted(
        p.describe().replace("kernel=fast", "kernel=simple") for p in firsts
    )
    # the headline counts the fast kernel's brute force: only its points are timed again
    assert {p.options["kernel"] for p in both if p.repeat} == {"fast"}


def test_quick_is_smaller_and_unknown_suite_refused():
    # no suite has more points quick than full (the meshes suite keeps 12 of its 18, three counts
    # a mesh for its fits, at 160x100), and the whole quick set traces under a tenth of the pixels
    for name in suites.SUITES:
        quick, full = ([p for p in suites.points([name], ["cpu"], quick=q) if not p.repeat] for q in (True, False))
        assert len(quick) <= len(full), name
    quick, full = ([p for p in suites.points(suites.SUITES, ["cpu"], quick=q) if not p.repeat] for q in (True, False))
    assert sum(p.width * p.height for p in quick) < sum(p.width * p.height for p in full) / 10
    with pytest.raises(RaybenchError, match="unknown suite"):
        suites.points(["thesys"], ["cpu"])


def test_summary_statistics(rng):
    samples = rng.lognormal(2.0, 0.3, 1001)
    s = stats.summarize(samples)
    assert s["median"] == pytest.approx(np.median(samples))
    assert s["mean"] == pytest.approx(samples.mean())
    assert s["p5"] == pytest.approx(np.percentile(samples, 5))
    assert s["p95"] == pytest.approx(np.percentile(samples, 95))
    assert s["min"] <= s["p5"] <= s["median"] <= s["p95"] <= s["max"]
    assert stats.summarize([7.0]) == {"mean": 7.0, "median": 7.0, "p5": 7.0, "p95": 7.0, "min": 7.0, "max": 7.0}


def test_linear_fit_recovers_a_known_line(rng):
    slope, intercept = rng.uniform(0.01, 5), rng.uniform(-3, 30)
    x = np.arange(100, 1001, 100)
    fit = stats.linear_fit(x, slope * x + intercept)
    assert fit["slope"] == pytest.approx(slope) and fit["intercept"] == pytest.approx(intercept, abs=1e-9)
    assert fit["r2"] == pytest.approx(1.0)
    curved = stats.linear_fit(x, (x / 100.0) ** 4)
    assert curved["r2"] < 0.95


def complete(**extra) -> dict:
    """The least record results.read accepts (its schema), and extra fields."""
    return {
        "suite": "thesis",
        "device": "cpu",
        "width": 8,
        "height": 6,
        "spheres": 10,
        "frame_ms": {"median": 2.0, "p5": 1.0, "p95": 3.0},
        "run": {"label": "x", "machine": {}},
        **extra,
    }


def test_results_round_trip_and_damage(tmp_path):
    path = tmp_path / "r.jsonl"
    with ResultsWriter(path) as w:
        for i in range(3):
            w.write(complete(i=i))
    assert [r["i"] for r in results.read(path)] == [0, 1, 2]
    # A half-written last line (a crash mid-write) is skipped with a warning.
    with open(path, "a") as f:
        f.write('{"format": "raybench-results", "version": 1, "suite": "th')
    with pytest.warns(UserWarning, match="cut short"):
        assert len(results.read(path)) == 3
    # Damage before the end, or a file that is not ours, is an error.
    lines = path.read_text().split("\n")
    (tmp_path / "mid.jsonl").write_text("\n".join([lines[0], "{oops", lines[1]]) + "\n")
    with pytest.raises(RaybenchError, match="line 2"):
        results.read(tmp_path / "mid.jsonl")
    (tmp_path / "other.jsonl").write_text('{"hello": 1}\n')
    with pytest.raises(RaybenchError, match="not a raybench result"):
        results.read(tmp_path / "other.jsonl")
    (tmp_path / "empty.jsonl").write_text("")
    with pytest.raises(RaybenchError, match="no results"):
        results.read(tmp_path / "empty.jsonl")


def _bench_subprocess(out, *extra):
    env = dict(os.environ, NUMBA_ENABLE_CUDASIM="0", PYTHONUNBUFFERED="1")
    # A shell that runs the tests in the background starts them with SIGINT
    # ignored, and Python then never turns it into KeyboardInterrupt: restore it.
    return subprocess.Popen(
        [
            sys.executable,
            "-m",
            "raybench",
            "bench",
            "--quick",
            "--device",
            "cpu",
            "--no-report",
            "--out",
            str(out),
            *extra,
        ],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        env=env,
        preexec_fn=sigint_default,
    )


def _wait_for_lines(folder, n, proc, timeout=600):
    deadline = time.time() + timeout
    while time.time() < deadline:
        files = list(folder.glob("*.jsonl"))
        if files and files[0].read_text().count("\n") >= n:
            return files[0]
        if proc.poll() is not None:
            pytest.fail(f"bench ended early: {proc.communicate()}")
        time.sleep(0.05)
    proc.kill()
    pytest.fail("no results appeared")


@pytest.mark.slow
@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM, signal.SIGKILL])
def test_interrupted_run_keeps_every_finished_point(tmp_path, sig):
    """SIGTERM as Ctrl-C: one line, every finished point kept, nothing else
    left (its default action had left a report's half-made folder and a
    "leaked semaphore" warning)."""
    proc = _bench_subprocess(tmp_path, "--suite", "thesis", "--duration", "0.5")
    path = _wait_for_lines(tmp_path, 2, proc)
    proc.send_signal(sig)
    out, err = proc.communicate(timeout=60)
    if sig == signal.SIGINT:
        assert proc.returncode == 130, (out, err)
        assert "interrupted" in err and "Traceback" not in err, err
    elif sig == signal.SIGTERM:
        assert proc.returncode == 143, (out, err)
        assert err.startswith("raybench: terminated (SIGTERM); the ") and err.count("\n") == 1, err
        assert [p.name for p in tmp_path.iterdir()] == [path.name]
    else:
        assert proc.returncode == -signal.SIGKILL
    records = results.read(path)  # every line whole: no warning, no error
    assert len(records) >= 2
    assert all(r["frame_ms"]["median"] > 0 for r in records)
    assert path.read_text().endswith("\n")


@pytest.mark.slow
def test_quick_run_end_to_end(tmp_path, capsys):
    """`raybench bench --quick` on the CPU: every suite, every record complete,
    and the report written."""
    code = run(
        [
            "bench",
            "--quick",
            "--suite",
            "all",
            "--device",
            "cpu",
            "--duration",
            "0.2",
            "--out",
            str(tmp_path),
            "--label",
            "ci",
        ]
    )
    out = capsys.readouterr().out
    assert code == 0, out
    (path,) = tmp_path.glob("results-*.jsonl")
    records = results.read(path)
    planned = suites.points(suites.SUITES, ["cpu"], quick=True, accels=suites.ACCELS)  # the CLI's default: both
    # a repeat of a headline point is written as a line of its own, and read back into its point's record
    expected = [p for p in planned if not p.repeat]
    assert len(records) == len(expected)
    again = [r for r in records if r.get("repeats")]
    assert sorted(r["spheres"] for r in again) == [100, 500, 1000]
    assert all(len(r["repeats"]) == 2 and r["repeats"][0]["samples_ms"] for r in again)
    for rec, point in zip(records, expected):
        assert (rec["suite"], rec["device"], rec["width"], rec["height"], rec["spheres"]) == (
            point.suite,
            point.device,
            point.width,
            point.height,
            point.spheres,
        )
        if "skipped" in rec:  # brute force past the scaling or secondary suite's cap: recorded, not measured
            assert rec["suite"] in ("scaling", "secondary") and "cap" in rec["skipped"]
            assert point.options["accel"] == "none"
            continue
        assert rec["frames"] >= 3 or rec["suite"] == "test7"
        f = rec["frame_ms"]
        assert 0 < f["p5"] <= f["median"] <= f["p95"]
        assert rec["kernel_ms"] is None  # the CPU has no separate kernel time
        assert rec["run"]["label"] == "ci" and rec["run"]["machine"]["cpu"]["physical_cores"] >= 1
        assert rec["run"]["settings"]["duration_s"] == 0.2
        assert rec["first_frame_s"] > 0
        # the multi-gpu suite's workers compile or load their kernels out of sight: not measured
        assert rec["compile_s"] is None if rec["suite"] == "multi-gpu" else rec["compile_s"] >= 0
    ramp = next(r for r in records if r["suite"] == "test7")
    assert ramp["series"]["spheres"] == list(range(20, 201, 10))  # the first frame (10 spheres) excluded
    assert len(ramp["series"]["frame_ms"]) == len(ramp["series"]["spheres"])
    assert "report:" in out
    # piped (capsys is no terminal): a line as each suite starts and one a point, with what is left
    progress = [line for line in out.splitlines() if line.startswith("[")]
    assert len(progress) == len(planned) and progress[0].startswith(f"[1/{len(planned)}] ")
    assert all(line.endswith(" left)") for line in progress)
    started = {line.split()[1].rstrip(":") for line in out.splitlines() if line.startswith("suite ")}
    assert started == {p.suite for p in expected}
    assert "the thesis's claims (the report has the rules and the reasons):" in out
    # the headline carries its interval over this run's frames, or says why it cannot
    assert re.search(r"this machine .* \((95% interval [\d.,]+ to [\d.,]+|too few frames for an interval.*)\)", out)
    report = next(tmp_path.glob("report-*/report.md"))
    assert "Verdict" in report.read_text() or "verdict" in report.read_text()
    # every measured point keeps its frames for compare's bootstrap (a ramp's are its series)
    for rec in records:
        if "skipped" in rec or rec["suite"] == "test7":
            continue
        if rec["suite"] != "multi-gpu":  # its samples are runs of several frames
            assert len(rec["samples_ms"]) == min(rec["frames"], 1000)
        assert np.isclose(np.median(rec["samples_ms"]), rec["frame_ms"]["median"], rtol=1e-4)
    # the headline ends the run: the geometric mean of rays/s at its three points, worked out here
    brute = [
        r
        for r in records
        if r["suite"] == "thesis" and (r["width"], r["height"]) == (800, 600) and r["options"].get("kernel") == "fast"
    ]
    assert sorted(r["spheres"] for r in brute) == [100, 500, 1000]
    # each point's median over all its passes' frames (its own and its repeats')
    medians = [np.median(np.concatenate([r["samples_ms"]] + [q["samples_ms"] for q in r["repeats"]])) for r in brute]
    expected = np.exp(np.mean(np.log([800 * 600 / m * 1e3 / 1e6 for m in medians])))
    line = next(line for line in out.splitlines() if line.startswith("  this machine"))
    assert line.split("  (")[0].split()[-1] == f"{expected:.3g}", (line, expected)  # then its interval, in brackets
    assert "reference machines (measured elsewhere" in out and "no GPU measured here" in out


@pytest.mark.parametrize(
    "args,needle",
    [
        (["--suite", "thesys"], "--suite"),
        (["--device", "tpu"], "--device"),
        (["--duration", "0"], "--duration"),
        (["--duration", "99999"], "--duration"),
        (["--label", "a b"], "--label"),
        # what the results' reader refuses is refused before the work, not after
        (["--label", ".."], "--label: must be a name of letters, digits"),
        (["--label", "x" * 65], "--label"),
        (["--seed", "18446744073709551616"], "--seed: must be a whole number from 0 to 1e+15"),
    ],
)
def test_bench_bad_input(tmp_path, capsys, args, needle):
    code = run(["bench", "--out", str(tmp_path / "r"), *args])
    err = capsys.readouterr().err
    assert code == 2 and err.count("\n") == 1 and needle in err and "Traceback" not in err, err
    assert not (tmp_path / "r").exists()


def test_a_suite_is_declared_once_in_the_registry(tmp_path, capsys, monkeypatch):
    """suites.REGISTRY is the one place a suite is named: bench --suite's choices and
    help, --suite all, the runner's dispatch, the record suites the schema takes and the
    report's sections are all read from it."""
    names = [s.name for s in suites.REGISTRY]
    assert list(suites.SUITES) == names and len(set(names)) == len(names)
    writes = [r for s in suites.REGISTRY for r in s.writes]
    assert list(results_schema.SUITES) == writes and len(set(writes)) == len(writes)
    assert list(suites.CAPPED) == [r for s in suites.REGISTRY if s.capped for r in s.writes]
    # each suite's points are its own records, timed in a way the runner knows
    for s in suites.REGISTRY:
        mine = suites.points([s.name], ["cpu", "cuda"], quick=True, cores=2, accels=suites.ACCELS, gpus=2)
        assert mine and {p.suite for p in mine} <= set(s.writes), s.name
        assert all(suites.owner(p.suite) is s for p in mine) and s.measure in ("frame", "dynamic", "workers")
    # the CLI: its help names every suite, an unknown one is refused with the registry's
    # names, and --suite all asks the runner for every one of them, in the registry's order
    from raybench.cli.bench import bench as command

    (option,) = [p for p in command.params if p.name == "suites"]
    assert all(s.help.startswith(s.name) and s.help in option.help for s in suites.REGISTRY)
    assert run(["bench", "--suite", "thesys", "--out", str(tmp_path / "r")]) == 2
    assert f"choose from {', '.join(names)} or all" in capsys.readouterr().err
    asked = []

    def plan(settings, label):
        asked.append(settings["suites"])
        raise RaybenchError("planned")

    monkeypatch.setattr(runner, "plan", plan)
    assert run(["bench", "--suite", "all", "--device", "cpu", "--out", str(tmp_path / "r")]) == 2
    assert asked == [names] and "planned" in capsys.readouterr().err


def test_report_bad_input(tmp_path, capsys):
    (tmp_path / "x.jsonl").write_text("not json\n")
    code = run(["report", str(tmp_path / "x.jsonl"), "-o", str(tmp_path / "rep")])
    err = capsys.readouterr().err
    assert code == 2 and "x.jsonl" in err and err.count("\n") == 1, err
    code = run(["report", str(tmp_path / "missing.jsonl"), "-o", str(tmp_path / "rep")])
    assert code == 2 and "no such results file" in capsys.readouterr().err


def test_scaling_points():
    pts = suites.points(["scaling"], ["cpu", "cuda"], accels=suites.ACCELS)
    for device in ("cpu", "cuda"):
        for accel in ("none", "bvh"):
            mine = [p for p in pts if p.device == device and p.options["accel"] == accel]
            even = [p for p in mine if "layout" not in p.options]
            assert [p.spheres for p in even if (p.width, p.height) == (1680, 1050)] == list(suites.SCALING_COUNTS)
            assert [(p.width, p.height, p.spheres) for p in even][-1] == (1920, 1080, 1_000_000)
            # only brute force is capped; the BVH runs every count
            assert all(("cap_s" in p.options) == (accel == "none") for p in mine)
            # the denser layouts: the BVH only, each at every count of theirs
            dense = [(p.options["layout"], p.spheres) for p in mine if "layout" in p.options]
            want = [(lay, n) for lay in suites.SCALING_LAYOUTS for n in suites.SCALING_LAYOUT_COUNTS]
            assert dense == (want if accel == "bvh" else [])
    assert suites.SCALING_COUNTS[0] == 10 and suites.SCALING_COUNTS[-1] == 1_000_000
    quick = suites.points(["scaling"], ["cpu"], quick=True, accels=suites.ACCELS)
    assert max(p.spheres for p in quick) <= 10_000 and len(quick) < len(pts) / 3


def test_scaling_cap_skips_and_records(tmp_path, monkeypatch, rng):
    """Brute force stops where the frame predicted from the last count
    measured (linear in spheres and pixels) passes the cap: the rest are
    recorded as skipped, none silently dropped."""
    per_sphere_ms = rng.uniform(0.5, 2.0)
    measured = []

    def fake_measure(point, scenes, duration):
        measured.append(point.spheres)
        median = per_sphere_ms * point.spheres * point.width * point.height / (1680 * 1050)
        return {
            "suite": point.suite,
            "device": point.device,
            "width": point.width,
            "height": point.height,
            "spheres": point.spheres,
            "options": point.options,
            "frame_ms": stats.summarize([median]),
        }

    monkeypatch.setattr(runner, "measure", fake_measure)
    pts = [p for p in suites.points(["scaling"], ["cpu"], accels=("none",))]
    with ResultsWriter(tmp_path / "r.jsonl") as w:
        runner.run(pts, w, {"label": "x", "machine": {}}, 0.1, 0, progress=False)
    recs = results.read(tmp_path / "r.jsonl")
    assert [r["spheres"] for r in recs] == [p.spheres for p in pts]
    cap_ms = suites.SCALING_CAP_S * 1e3
    done = [r["spheres"] for r in recs if "skipped" not in r]
    assert done == measured == [n for n in suites.SCALING_COUNTS if n == 10 or per_sphere_ms * n <= cap_ms]
    first_skip = next(r for r in recs if "skipped" in r)
    assert first_skip["predicted_ms"] > cap_ms and "cap" in first_skip["skipped"]
    assert all("skipped" in r for r in recs[recs.index(first_skip) :])


@pytest.mark.gpu
def test_cuda_bvh_records_its_walk():
    """Which BVH walk cuda chose for the tree is in the record (under the simulator here)."""
    from raybench.backends import cuda as cuda_backend

    if not cuda_backend.available():
        pytest.skip("no CUDA GPU and the simulator is off")
    point = suites.Point("scaling", "cuda", 16, 8, 20, {"accel": "bvh", "label": "bvh"})
    record = runner.measure(point, runner.Scenes(0), 0.01)
    assert record["walk"] == "ray" and record["build_s"] >= 0
    cpu = runner.measure(
        suites.Point("scaling", "cpu", 16, 8, 20, {"accel": "bvh", "label": "bvh"}), runner.Scenes(0), 0.01
    )
    assert "walk" not in cpu


def test_record_names_the_commit_given_in_the_environment(monkeypatch):
    """The GPU machine's git metadata is stale: RAYBENCH_GIT_COMMIT, where set,
    is the commit a record names; unset, the checkout's own git answers."""
    from raybench import machine

    monkeypatch.delenv(machine.GIT_COMMIT_ENV, raising=False)
    from_git = machine.git_commit()
    monkeypatch.setenv(machine.GIT_COMMIT_ENV, "0123456789ab")
    assert runner.run_info({}, "x", {})["git_commit"] == "0123456789ab"
    assert from_git != "0123456789ab"
    monkeypatch.setenv(machine.GIT_COMMIT_ENV, "  ")  # blank is unset, not a commit
    assert machine.git_commit() == from_git


def test_secondary_points():
    """The secondary suite: the thesis's three sizes x 1,000, 10,000 and
    100,000 spheres, on every device, through the BVH and by brute force (the
    simple kernel whatever kernels were asked for, capped), each Whitted
    point (depth 5, 4 shadow samples) beside its thesis-shading twin."""
    devices = ["cpu", "cuda", "wgpu"]
    pts = suites.points(["secondary"], devices, accels=suites.ACCELS, kernels=("fast",), wgpu={"adapter": "x"})
    assert {p.suite for p in pts} == {"secondary"}
    grid = {(w, h, n) for w, h in ((800, 600), (1280, 800), (1680, 1050)) for n in (1000, 10_000, 100_000)}
    for device in devices:
        for accel in ("bvh", "none"):
            mine = [p for p in pts if p.device == device and p.options["accel"] == accel]
            for shading in ("thesis", "whitted"):
                got = [(p.width, p.height, p.spheres) for p in mine if p.options["shading"] == shading]
                assert len(got) == len(set(got)) == 9 and set(got) == grid
            whitted = [p for p in mine if p.options["shading"] == "whitted"]
            assert all(p.options["depth"] == 5 and p.options["shadow_samples"] == 4 for p in whitted)
            assert all("depth" not in p.options for p in mine if p.options["shading"] == "thesis")
            if accel == "none":
                assert {p.options["kernel"] for p in mine} == {"simple"}
                assert {p.options["cap_s"] for p in mine} == {suites.SECONDARY_CAP_S}
            else:
                assert all("cap_s" not in p.options and "kernel" not in p.options for p in mine)
            assert all(p.options.get("adapter") == ("x" if device == "wgpu" else None) for p in mine)
    # each Whitted point right after its twin: an interrupted run keeps whole pairs
    for a, b in zip(pts[::2], pts[1::2]):
        assert (a.options["shading"], b.options["shading"]) == ("thesis", "whitted")
        assert (a.device, a.width, a.height, a.spheres) == (b.device, b.width, b.height, b.spheres)
    assert len(suites.points(["secondary"], ["cpu"], accels=("bvh",))) == 18
    quick = suites.points(["secondary"], ["cpu"], quick=True, accels=suites.ACCELS)
    assert len(quick) < len(pts) / 6 and max(p.width * p.height for p in quick) <= 320 * 200
    assert "secondary" in suites.SUITES  # so --suite all includes it


# The fields of a record of the thesis's shading, as before the secondary suite:
# its records must stay exactly as they were (older results files still report).
THESIS_RECORD_KEYS = {
    "suite", "test", "device", "width", "height", "spheres", "options", "frames", "frame_ms", "kernel_ms",
    "first_frame_s", "compile_s", "build_s", "rays_per_s", "tests_per_s", "samples_ms",
}  # fmt: skip


@pytest.mark.slow
def test_secondary_quick_run_counts_the_rays_a_render_casts(tmp_path, capsys, monkeypatch, rng):
    """`raybench bench --suite secondary --quick` on the CPU (its quick set
    shrunk to tiny frames): every Whitted record holds the rays by kind that
    raybench.render(..., shading="whitted") counts for the same scene, size
    and way, rays/s from them and the median frame, and the shading
    settings; the thesis-shading twins are records as any other suite's."""
    import raybench

    monkeypatch.setattr(suites, "QUICK_SECONDARY_SIZES", ((24, 16), (16, 12)))
    monkeypatch.setattr(suites, "QUICK_SECONDARY_COUNTS", (int(rng.integers(5, 40)), int(rng.integers(40, 120))))
    seed = int(rng.integers(0, 1000))
    args = ["bench", "--quick", "--suite", "secondary", "--device", "cpu", "--duration", "0.05"]
    code = run([*args, "--seed", str(seed), "--out", str(tmp_path), "--label", "ci"])
    out = capsys.readouterr().out
    assert code == 0, out
    (path,) = tmp_path.glob("results-*.jsonl")
    records = results.read(path)
    expected = suites.points(["secondary"], ["cpu"], quick=True, accels=suites.ACCELS)
    assert [(r["width"], r["height"], r["spheres"], r["options"]) for r in records] == [
        (p.width, p.height, p.spheres, p.options) for p in expected
    ]
    whitted = [r for r in records if r["options"]["shading"] == "whitted"]
    assert len(whitted) == len(records) // 2 and not any("skipped" in r for r in records)
    for r in whitted:
        scene = raybench.random_spheres(r["spheres"], seed, materials=True)
        frame = raybench.render(
            scene, width=r["width"], height=r["height"], device="cpu", shading="whitted",
            depth=r["options"]["depth"], shadow_samples=r["options"]["shadow_samples"],
            accel=r["options"]["accel"],
        )  # fmt: skip
        assert r["rays"] == frame.rays and r["rays"]["primary"] == r["width"] * r["height"]
        assert r["rays"]["shadow"] > 0 and r["rays_per_frame"] == sum(frame.rays.values())
        assert r["rays_per_s"] == pytest.approx(r["rays_per_frame"] / (r["frame_ms"]["median"] / 1e3))
        assert r["kernel_rays_per_s"] is None and r["tests_per_s"] is None  # the CPU has no kernel clock
        assert (r["options"]["depth"], r["options"]["shadow_samples"]) == (5, 4)
    # the same spheres lit differently: the twins cast one ray a pixel and record no kinds
    for r in records:
        if r["options"]["shading"] == "thesis":
            assert set(r) - {"format", "version", "run"} == THESIS_RECORD_KEYS
            assert r["rays_per_s"] == pytest.approx(r["width"] * r["height"] / (r["frame_ms"]["median"] / 1e3))
    assert "report:" in out
    text = next(tmp_path.glob("report-*/report.md")).read_text()
    assert f"**{report.SECONDARY_QUESTION}** **not measured**: cannot be decided" in text  # the CPU alone


def test_thesis_records_keep_their_fields():
    """A thesis-shading point's record has exactly the fields it had before
    Whitted points existed, and the frames' times that compare bootstraps."""
    point = suites.Point("thesis", "cpu", 8, 6, 5, {"kernel": "simple", "accel": "none"}, test=4)
    record = runner.measure(point, runner.Scenes(0), 0.01)
    assert set(record) == THESIS_RECORD_KEYS


def test_secondary_cap_skips_brute_force_and_records(tmp_path, monkeypatch, rng):
    """The secondary suite's brute force stops where a frame predicted from
    the last one of its series (same device, way and shading) passes the cap;
    the BVH is never skipped, and every point is recorded."""
    per_ray_ms = rng.uniform(1e-6, 1e-4)  # per pixel and sphere

    def exact_ms(point):
        return (
            per_ray_ms
            * (12 if point.options["shading"] == "whitted" else 1)
            * point.width
            * point.height
            * point.spheres
        )

    def fake_measure(point, scenes, duration):
        keys = ("suite", "device", "width", "height", "spheres", "options")
        return {**{k: getattr(point, k) for k in keys}, "frame_ms": stats.summarize([exact_ms(point)])}

    monkeypatch.setattr(runner, "measure", fake_measure)
    pts = suites.points(["secondary"], ["cpu"], accels=suites.ACCELS)
    with ResultsWriter(tmp_path / "r.jsonl") as w:
        runner.run(pts, w, {"label": "x", "machine": {}}, 0.1, 0, progress=False)
    recs = results.read(tmp_path / "r.jsonl")
    assert [(r["width"], r["height"], r["spheres"], r["options"]) for r in recs] == [
        (p.width, p.height, p.spheres, p.options) for p in pts
    ]
    cap_ms = suites.SECONDARY_CAP_S * 1e3
    skips = 0
    for r, p in zip(recs, pts):
        first = p.spheres == 1000 and (p.width, p.height) == (800, 600)  # nothing to predict from
        if p.options["accel"] == "bvh" or first:
            assert "skipped" not in r
        else:
            assert ("skipped" in r) == (exact_ms(p) > cap_ms)
            if "skipped" in r:
                skips += 1
                assert r["predicted_ms"] == pytest.approx(exact_ms(p)) and "cap" in r["skipped"]
    assert skips > 0  # at least 100,000 spheres' Whitted frames: 12 x 1680 x 1050 x 1e5 x 1e-6 ms > the cap


def test_whitted_record_rates_from_frame_and_kernel_time(monkeypatch, rng):
    """Where the device has its own clock, a Whitted record's rays/s come from
    the median frame and, apart, the median kernel time; the rays are the
    tracer's counts, by kind. A stand-in tracer gives known times and counts."""
    counts = rng.integers(1, 10**7, 4)
    frames = iter(rng.uniform(5, 50, 1000))
    seen = {}

    class Fake:
        walk, build_s, ray_counts = None, None, np.zeros(4, np.int64)

        def __init__(self, device, spheres, width, height, **options):
            seen.update(options, spheres=spheres.shape[1])

        def describe(self):
            return None

        def compile(self):
            return 0.0

        def timed_trace(self, basis, count=None):
            self.ray_counts[:] = counts
            return next(frames)

        def close(self):
            pass

    monkeypatch.setattr(runner.backends, "tracer", Fake)
    monkeypatch.setattr(runner, "WARMUP_S", 0.0)
    opts = {"accel": "bvh", "shading": "whitted", "depth": 3, "shadow_samples": 2}
    record = runner.measure(suites.Point("secondary", "cuda", 40, 30, 12, opts), runner.Scenes(0), 0.0)
    # the Shading travels as shading=, the record's "whitted" and depth not as device options
    assert isinstance(seen["shading"], lighting.Shading) and seen["spheres"] == 12
    assert seen["shading"].depth == 3 and seen["shading"].shadow_samples == 2
    assert seen["accel"] == "bvh" and "depth" not in seen and "shadow_samples" not in seen
    assert record["rays"] == dict(zip(("primary", "shadow", "reflection", "refraction"), counts.tolist()))
    assert record["rays_per_frame"] == counts.sum() and record["options"] == opts
    assert record["rays_per_s"] == pytest.approx(counts.sum() / (record["frame_ms"]["median"] / 1e3))
    assert record["kernel_rays_per_s"] == pytest.approx(counts.sum() / (record["kernel_ms"]["median"] / 1e3))


def test_multi_gpu_worker_counts():
    assert suites.worker_counts("cuda", 16, 2) == [1, 2]
    assert suites.worker_counts("cuda", 16, 8) == list(range(1, 9))
    assert suites.worker_counts("cpu", 6, 0) == [1, 2, 4, 6]
    assert suites.worker_counts("cpu", 8, 0) == [1, 2, 4, 8]
    assert suites.worker_counts("cpu", 1, 0) == [1]


def multi_record(rng, device, job, workers, ms):
    return {"suite": "multi-gpu", "device": device, "width": 64, "height": 48, "spheres": 10,
            "options": {"workers": workers, "job": job, "accel": "bvh"}, "frame_ms": {"median": ms}}  # fmt: skip


def test_multi_gpu_series_against_linear(rng):
    one, two, four = rng.uniform(1, 100, 3)
    records = [multi_record(rng, "cuda", "frame", n, ms) for n, ms in ((4, four), (1, one), (2, two))]
    records.append(multi_record(rng, "cpu", "sequence", 2, two))  # a series without its one-worker point
    cpu, cuda = report.multi_gpu_series(records)
    assert [p["workers"] for p in cuda["points"]] == [1, 2, 4] and cuda["one"] == pytest.approx(1e3 / one)
    for p, ms in zip(cuda["points"], (one, two, four)):
        assert p["frames_per_s"] == pytest.approx(1e3 / ms)
        assert p["speedup"] == pytest.approx(one / ms)
        assert p["efficiency"] == pytest.approx(one / ms / p["workers"])
    assert cpu["one"] is None and cpu["points"][0]["speedup"] is None and cpu["points"][0]["efficiency"] is None


@pytest.mark.slow
def test_multi_gpu_suite_on_cpu_workers_end_to_end(tmp_path, capsys):
    """bench --suite multi-gpu on 1 and 2 CPU workers: records the schema takes, and a report that sets the
    two workers against one and against linear."""
    argv = ["bench", "--quick", "--suite", "multi-gpu", "--device", "cpu", "--duration", "0.05", "--accel", "bvh",
            "--out", str(tmp_path), "--label", "ci"]  # fmt: skip
    assert run(argv) == 0, capsys.readouterr().err
    (path,) = tmp_path.glob("results-*.jsonl")
    records = results.read(path)
    counts = suites.worker_counts("cpu", os.cpu_count() or 1, 0)
    assert [(r["options"]["workers"], r["options"]["job"]) for r in records] == [
        (n, job) for n in counts for job in ("frame", "sequence")
    ]
    for r in records:
        assert r["frames"] >= 3 * (r["options"].get("frames") or 1)
        assert r["frames_per_s"] == pytest.approx(1e3 / r["frame_ms"]["median"])
    text = next(tmp_path.glob("report-*/report.md")).read_text()
    assert "ci: across workers" in text and "| 2 |" in text and "efficiency" in text
    assert next(tmp_path.glob("report-*/ci-multi-gpu.png")).stat().st_size > 1000


def test_builds_split_gpu_bvh_points_only():
    """--build host --build gpu: each cuda and wgpu BVH point twice, one per
    build; brute force and the cpu once, as without."""
    devices, wgpu = ["cpu", "cuda", "wgpu"], {"adapter": "x"}
    plain = suites.points(["scaling"], devices, accels=("bvh", "none"), wgpu=wgpu)
    both = suites.points(["scaling"], devices, accels=("bvh", "none"), wgpu=wgpu, builds=("host", "gpu"))
    gpu_bvh = [p for p in plain if p.device != "cpu" and p.options["accel"] == "bvh"]
    assert {p.device for p in gpu_bvh} == {"cuda", "wgpu"}
    assert len(both) == len(plain) + len(gpu_bvh)
    for build in ("host", "gpu"):
        got = [(p.device, p.spheres) for p in both if p.options.get("build") == build]
        assert got == [(p.device, p.spheres) for p in gpu_bvh]
    assert all("build" not in p.options for p in both if p.device == "cpu" or p.options["accel"] == "none")


def test_dynamic_points_are_bvh_with_cuda_and_wgpu_once_per_build():
    pts = suites.points(["dynamic"], ["cpu", "cuda", "wgpu"], wgpu={"adapter": "x"})
    assert {p.spheres for p in pts} == set(suites.DYNAMIC_COUNTS)
    assert all(p.options["accel"] == "bvh" and p.options["motion"] == "orbits" for p in pts)
    builds = sorted((p.device, p.options.get("build", "-")) for p in pts if p.spheres == 10_000)
    assert builds == [("cpu", "-"), ("cuda", "gpu"), ("cuda", "host"), ("wgpu", "gpu"), ("wgpu", "host")]
    assert all(p.options["adapter"] == "x" for p in pts if p.device == "wgpu")
    only = suites.points(["dynamic"], ["cuda"], builds=("gpu",))
    assert {p.options["build"] for p in only} == {"gpu"}


def test_dynamic_record_times_the_update_in_each_frame(tmp_path):
    """A measured dynamic point (cpu: the tree rebuilt every frame) passes the
    results schema; its update is part of its frame, and every frame rebuilt."""
    point = suites.Point("dynamic", "cpu", 16, 8, 40, {"accel": "bvh", "motion": "orbits"})
    record = runner.measure_dynamic(point, runner.Scenes(0), 0.05)
    assert record["updates"] == {"build": record["frames"]} and record["frames"] >= runner.MIN_FRAMES
    assert 0 < record["update_ms"]["median"] <= record["frame_ms"]["median"]
    assert 0 < record["update_share"] < 1
    assert record["frames_per_s"] == pytest.approx(1e3 / record["frame_ms"]["median"])
    with ResultsWriter(tmp_path / "r.jsonl") as w:
        w.write({**record, "run": {"label": "x", "machine": {}}})
    (back,) = results.read(tmp_path / "r.jsonl")
    assert back["updates"] == record["updates"]
