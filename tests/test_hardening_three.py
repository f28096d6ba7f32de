"""Issue 39's items that have no test file of their own: a report's folder
checked before the work, parts records without samples compared, the API's
options checked for type at its edge. Each test failed before its fix."""

import contextlib
import json
import time

import numpy as np
import pytest
from test_compare import point

import raybench
from raybench import RaybenchError
from raybench.bench import compare, results
from raybench.cli import run


def part(median: float, **extra) -> dict:
    return {
        "format": results.FORMAT,
        "version": results.VERSION,
        "suite": "parts",
        "quantity": "bvh-build",
        "device": "cpu",
        "time_ms": {"median": median, "p5": 1.0, "p95": 4.0},
        "run": point([1.0], 1)["run"],
        **extra,
    }


@pytest.mark.parametrize("out", [".", "", "..", "/"])
def test_report_refuses_a_folder_it_cannot_replace_before_any_work(tmp_path, monkeypatch, capsys, out):
    """report -o . and -o '' raised ValueError after all the work: the folder is made
    aside and renamed into place, and "." names none to rename."""
    monkeypatch.chdir(tmp_path)
    (tmp_path / "r.jsonl").write_text(json.dumps(part(2.0)) + "\n")
    assert run(["report", "r.jsonl", "-o", out]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "name a new or empty folder for the report" in err, err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["r.jsonl"]


def test_parts_without_samples_are_compared_without_a_traceback(tmp_path, capsys):
    """A parts record may leave out its sample count: compare raised TypeError (int(None))."""
    old, new = tmp_path / "old.jsonl", tmp_path / "new.jsonl"
    old.write_text(json.dumps(part(2.0)) + "\n")
    new.write_text(json.dumps(part(3.0)) + "\n")
    (c,) = compare.compare(results.read(old), results.read(new)).changes
    assert c.verdict == compare.TOO_FEW and c.ratio == 1.5
    assert run(["compare", str(old), str(new)]) == 0
    assert "parts bvh-build cpu" in capsys.readouterr().out


API_TYPES = [
    ({"kernel": "simple", "accel": "none", "constant_count": "no"}, "constant_count: must be True or False, got 'no'"),
    ({"kernel": "simple", "accel": "none", "constant_count": 1}, "constant_count: must be True or False, got 1"),
    ({"tree_width": 2.0}, "tree_width: must be one of 2, 4, got 2.0"),
    ({"tree_width": np.array(2)}, "tree_width: must be one of 2, 4, got 2"),
    ({"tree_width": np.array([2, 4])}, "tree_width: must be one of 2, 4, got [2, 4]"),
    ({"accel": np.array(["bvh"])}, "accel: must be one of bvh, none, got ['bvh']"),
    ({"accel": "none", "kernel": np.array(["fast"])}, "kernel: must be one of fast, simple, got ['fast']"),
    ({"device": np.array([1.0, 2.0])}, "device: must be one of"),
    ({"shading": np.array([1.0, 2.0])}, "shading: must be one of"),
    ({"threads": np.array([2])}, "threads: must be an integer from 1"),
]


@pytest.mark.parametrize("given, message", API_TYPES, ids=[str(i) for i in range(len(API_TYPES))])
def test_api_options_are_checked_for_type_at_the_edge(given, message):
    """ "no" was truthy and taken, 2.0 and an array passed `in (2, 4)`, and an
    array of two raised NumPy's ValueError from deep inside: each is now the
    CLI's one line, naming the parameter, before any work."""
    scene = raybench.random_spheres(5, seed=1)
    with pytest.raises(RaybenchError) as caught:
        raybench.render(scene, width=8, height=8, **{"device": "cpu", **given})
    assert str(caught.value).startswith(message), str(caught.value)
    assert "\n" not in str(caught.value)


def test_a_true_flag_is_still_taken():
    from raybench.backends import options

    for flag in (True, np.bool_(True)):
        assert options.checked("cpu", {"accel": "none", "kernel": "simple", "constant_count": flag}).constant_count


def test_one_renderer_from_two_threads_gives_each_its_own_camera():
    """One Renderer used by two threads at once mixed their cameras (8 to 52 of
    60 frames came out with the other thread's view): its calls now take
    turns, so every frame is its own camera's, as a Renderer alone makes it."""
    import threading

    scene = raybench.random_spheres(60, seed=3)
    cameras = [raybench.Camera(position=(x, 0.0, -20.0), look_at=(0.0, 0.0, 0.0)) for x in (-8.0, 8.0)]
    with raybench.Renderer(scene, 48, 32, device="cpu", threads=2) as alone:
        expected = [alone.render(camera).image for camera in cameras]
    assert not np.array_equal(*expected)  # the two views differ, so a mixed frame would show
    wrong = []
    with raybench.Renderer(scene, 48, 32, device="cpu", threads=2) as shared:
        shared.compile()
        start = threading.Barrier(2)

        def frames(i):
            start.wait()
            for _ in range(30):
                if not np.array_equal(shared.render(cameras[i]).image, expected[i]):
                    wrong.append(i)

        threads = [threading.Thread(target=frames, args=(i,)) for i in (0, 1)]
        for t in threads:
            t.start()
        for t in threads:
            t.join(timeout=120)
        assert not any(t.is_alive() for t in threads)
    assert not wrong, f"{len(wrong)} of 60 frames had the other thread's view"


def test_sigterm_while_a_report_is_made_leaves_nothing(tmp_path):
    """SIGTERM's default action ended the process where it stood: the report's
    folder, made aside (.rep.XXXX.partial), stayed behind. It now ends as
    Ctrl-C does: the folder removed, one line, exit 143."""
    import os
    import signal
    import subprocess
    import sys
    import time
    from pathlib import Path

    root = Path(__file__).resolve().parent.parent
    env = {**os.environ, "PYTHONPATH": str(root / "src")}
    out = tmp_path / "out"
    out.mkdir()
    argv = [sys.executable, "-m", "raybench", "report", str(root / "benchmarks" / "results"), "-o", str(out / "rep")]
    proc = subprocess.Popen(argv, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        deadline = time.monotonic() + 120
        while not list(out.glob(".rep.*.partial")) and proc.poll() is None and time.monotonic() < deadline:
            time.sleep(0.02)
        assert list(out.glob(".rep.*.partial")), "the report's folder was not under way in time"
        proc.send_signal(signal.SIGTERM)
        _, err = proc.communicate(timeout=60)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.communicate(timeout=30)
    # (the blank line before it is click's, as after Ctrl-C's ^C)
    assert proc.returncode == 143 and err.strip() == "raybench: terminated (SIGTERM)", (proc.returncode, err)
    assert list(out.iterdir()) == []


def test_the_tests_that_send_sigint_pass_when_it_is_inherited_ignored(tmp_path):
    """A shell that starts the tests in the background (a script's `&`)
    starts them with SIGINT ignored; the tests that send it then failed. Those
    in this process take Python's handler for their time (conftest's
    sigint_handled), their children its default (sigint_default): run here
    with SIGINT ignored, as such a shell starts them."""
    import os
    import signal
    import subprocess
    import sys
    from pathlib import Path

    tests = Path(__file__).resolve().parent
    env = {**os.environ, "PYTHONPATH": str(tests.parent / "src")}
    argv = [sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider", "-k", "ctrl_c_during_a_write",
            str(tests / "test_hardening.py")]  # fmt: skip
    done = subprocess.run(
        argv, env=env, cwd=tmp_path, capture_output=True, text=True, timeout=300,
        preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_IGN),
    )  # fmt: skip
    assert done.returncode == 0 and "2 passed" in done.stdout, done.stdout[-2000:]


def test_ctrl_c_while_a_cluster_starts_is_raised_once_it_is_whole(sigint_handled):
    """Ctrl-C raised inside Dask's start of an embedded cluster left it half
    made, and Dask's exit hook failed on it with a traceback: it is now held
    until the start is done (cluster.client._ctrl_c_after), where Cluster
    closes what it started, then raised."""
    import os
    import signal

    pytest.importorskip("distributed")
    from raybench.cluster.client import _ctrl_c_after

    reached = []
    with pytest.raises(KeyboardInterrupt):
        with _ctrl_c_after():
            os.kill(os.getpid(), signal.SIGINT)
            reached.append("the start went on to its end")
    assert reached and signal.getsignal(signal.SIGINT) is signal.default_int_handler


def test_the_compile_spinner_says_ctrl_c_waits_for_the_compile(tmp_path, monkeypatch):
    """Ctrl-C during Numba's first compile waits for LLVM to return (seconds to a
    minute), which looked like a hang: the terminal's spinner says so plainly."""
    import io

    from rich.console import Console

    from raybench import compiled
    from raybench.cli import compiling

    monkeypatch.setattr(compiled, "CACHE_DIR", tmp_path)
    out = io.StringIO()
    with compiling.announced(Console(file=out, force_terminal=True, width=80)):  # one line on a plain terminal
        compiled.on_compile()  # what a cache miss calls
    shown = " ".join(out.getvalue().split())
    assert "(Ctrl-C waits for it)" in shown, shown


@pytest.mark.slow
@pytest.mark.parametrize("delay", [0.1, 0.4])
def test_ctrl_c_while_the_workers_start_is_one_line(tmp_path, delay):
    """Ctrl-C at a terminal reaches the whole process group: the embedded
    cluster's workers, spawned and still importing, raised their own
    KeyboardInterrupt before any handler of theirs was set, and printed 2 or
    3 tracebacks (each of these delays did, on the 2-vCPU machine). They now
    start with it blocked (cluster.client._ctrl_c_after)."""
    import sys

    import psutil
    from test_cluster import blocks, interrupted_when

    from raybench import sequence
    from raybench.cluster import sharedframe

    out = tmp_path / "frames"
    argv = [sys.executable, "-m", "raybench", "render", "--spheres", "200", "--size", "64x48", "--device", "cpu",
            "--workers", "2", "--path", "orbit", "--frames", "50", "-o", str(out)]  # fmt: skip

    def workers_spawned(proc) -> bool:  # both workers' processes are there, importing, `delay` s ago
        spawned = 0
        for child in psutil.Process(proc.pid).children(recursive=True):
            with contextlib.suppress(psutil.Error):
                spawned += "spawn_main" in " ".join(child.cmdline())
        if spawned < 2:
            return False
        time.sleep(delay)
        return True

    with interrupted_when(argv, workers_spawned) as (proc, family, err):
        named = f"{sharedframe.PREFIX}{proc.pid}-"
    assert proc.returncode == 130 and err.strip() == "raybench: interrupted" and "Traceback" not in err, err
    _, alive = psutil.wait_procs(family, timeout=20)
    assert not alive, f"stray processes: {alive}"
    assert not any(name.startswith(named) for name in blocks())
    # (the folder's marker, written before the cluster starts, is what a run resumes by)
    assert not out.exists() or {p.name for p in out.iterdir()} <= {sequence.MARKER}, sorted(out.iterdir())


def test_ctrl_c_as_a_record_is_synced_keeps_it(tmp_path, monkeypatch, sigint_handled):
    """Ctrl-C or SIGTERM that came while a whole record was being synced to
    disk cut it off again: a finished point the file had shown was lost (a
    bench stopped by SIGTERM kept 1 of the 2 records seen, once, on a loaded
    machine). It is now raised once the record is on disk, and counted."""
    import os
    import signal

    record = {k: v for k, v in point([1.0, 2.0, 3.0], 3).items() if k not in ("format", "version")}
    writer = results.ResultsWriter(tmp_path / "r.jsonl")
    writer.write(record)
    synced = os.fsync

    def synced_then_ctrl_c(fd):
        synced(fd)
        os.kill(os.getpid(), signal.SIGINT)  # Python raises it as fsync returns

    monkeypatch.setattr(os, "fsync", synced_then_ctrl_c)
    with pytest.raises(KeyboardInterrupt):
        writer.write(record)
    monkeypatch.undo()
    writer.close()
    assert len(results.read(tmp_path / "r.jsonl")) == writer.count == 2
