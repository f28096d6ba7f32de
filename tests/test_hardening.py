"""Regression tests for issue 18's defect classes: each bad input found by
hand is refused in one line (RaybenchError, exit code 2, no traceback, no
file left behind), and faults during work keep what was already written."""

from __future__ import annotations

import errno
import json
import os
import re
import resource
import signal
import stat
import subprocess
import sys
import time
import warnings
from pathlib import Path

import numpy as np
import pytest
from test_report import machine, rec, set_at, write

import raybench
from raybench import Camera, RaybenchError, Scene, files
from raybench.bench import report, results
from raybench.cli import run

ERROR = "raybench: error: "
SRC = str(Path(raybench.__file__).parent.parent)


@pytest.fixture(autouse=True)
def in_tmp(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    return tmp_path


def tree(folder) -> set[str]:
    return {str(p.relative_to(folder)) for p in Path(folder).rglob("*")}


def one_line(capsys, args, *needles, code=2) -> str:
    """Run the CLI in-process: exit code 2, one stderr line naming every needle, no traceback."""
    got = run([str(a) for a in args])
    out, err = capsys.readouterr()
    assert "Traceback" not in out + err, err
    assert got == code, (got, out, err)
    lines = err.splitlines()
    assert len(lines) == 1 and lines[0].startswith(ERROR), err
    for needle in needles:
        assert needle in lines[0], (needle, lines[0])
    return lines[0]


def scene_doc(n=2, **extra):
    doc = {
        "format": "raybench-scene",
        "version": 1,
        "spheres": [{"center": [0, 0, 5 + i], "radius": 0.5, "color": [1, 0, 0]} for i in range(n)],
    }
    doc.update(extra)
    return doc


def nested(depth: int) -> str:
    return "[" * depth + "]" * depth


# --- 1. deeply nested JSON ----------------------------------------------------------


@pytest.mark.parametrize("depth", [files.MAX_JSON_DEPTH + 1, 100_000])
def test_deep_json_scene_is_one_line(capsys, tmp_path, depth):
    path = tmp_path / "deep.json"
    path.write_text('{"format": "raybench-scene", "version": 1, "spheres": ' + nested(depth) + "}")
    before = tree(tmp_path)
    one_line(capsys, ["render", "--scene", path, "--size", "8x6", "--device", "cpu"], "deep.json", "nested")
    assert tree(tmp_path) == before


def test_deep_json_results_is_one_line_and_no_report_folder(capsys, tmp_path, rng):
    path = write(tmp_path / "r.jsonl", [rec("thesis", "cpu", 100, 5.0)])
    with open(path, "a") as f:
        f.write(nested(50_000) + "\n")
    one_line(capsys, ["report", path, "-o", tmp_path / "rep"], "r.jsonl: line 2", "nested")
    assert not (tmp_path / "rep").exists()


def test_depth_cap_is_exact():
    """At the cap a document is read; one deeper is not. Brackets in strings do not count."""
    assert files.loads(nested(files.MAX_JSON_DEPTH), "x") is not None
    with pytest.raises(RaybenchError, match=f"nested {files.MAX_JSON_DEPTH + 1} deep"):
        files.loads(nested(files.MAX_JSON_DEPTH + 1), "x")
    assert files.loads(json.dumps(["[" * 100, '\\"[[[' * 50]), "x") == ["[" * 100, '\\"[[[' * 50]


def test_depth_counts_each_branch_not_the_brackets_in_all():
    """Siblings close what they open: ten shallow ones and then one 33 deep is 33 deep."""
    doc = "[" + ",".join([nested(2)] * 10 + [nested(files.MAX_JSON_DEPTH)]) + "]"
    with pytest.raises(RaybenchError, match=f"nested {files.MAX_JSON_DEPTH + 1} deep"):
        files.loads(doc, "x")
    pretty = json.dumps(json.loads(nested(files.MAX_JSON_DEPTH + 1)), indent=1)  # a bracket a line
    with pytest.raises(RaybenchError, match=f"nested {files.MAX_JSON_DEPTH + 1} deep"):
        files.loads(pretty, "x")


def test_each_results_line_starts_again_at_depth_zero(tmp_path):
    """A damaged line that leaves brackets open is reported as not JSON, by
    its number; its open brackets do not count against the next line."""
    record = rec("thesis", "cpu", 100, 5.0)
    record["extra"] = json.loads(nested(20))
    path = tmp_path / "r.jsonl"
    line = json.dumps({"format": "raybench-results", "version": 1, **record})
    path.write_text("[" * 20 + "\n" + line + "\n")
    with pytest.raises(RaybenchError, match=r"r.jsonl: line 1: not valid JSON"):
        results.read(path)
    # and the cap holds on every line, the first and a later one, below Python's recursion limit
    deep = nested(files.MAX_JSON_DEPTH + 1)
    for lines, number in (([deep, line], 1), ([line, line, deep], 3)):
        path.write_text("\n".join(lines) + "\n")
        with pytest.raises(RaybenchError, match=f"r.jsonl: line {number}: JSON nested {files.MAX_JSON_DEPTH + 1} deep"):
            results.read(path)


def test_an_integer_too_long_for_python_is_one_line(capsys, tmp_path):
    """Python refuses to read integers of more than 4300 digits (a ValueError, not a JSONDecodeError)."""
    (tmp_path / "s.json").write_text(json.dumps(scene_doc(1)).replace('"radius": 0.5', '"radius": ' + "7" * 5000))
    one_line(capsys, ["render", "--scene", "s.json", "--device", "cpu"], "s.json: not valid JSON", "4300")


def test_the_size_limit_is_exact_and_holds_for_files_that_report_no_size(tmp_path):
    """max_bytes is allowed, one more is not; a /proc file says it holds 0
    bytes and holds more, and is still cut at the limit."""
    path = tmp_path / "ten.json"
    path.write_text("0123456789")
    assert files.read_text(path, "scene file", max_bytes=10) == "0123456789"
    with pytest.raises(RaybenchError, match="ten.json: the scene file is 0 MiB, over the limit"):
        files.read_text(path, "scene file", max_bytes=9)
    assert os.stat("/proc/self/status").st_size == 0
    with pytest.raises(RaybenchError, match="/proc/self/status: the scene file is over the limit of 0 MiB$"):
        files.read_text("/proc/self/status", "scene file", max_bytes=20)
    assert len(files.read_text("/proc/self/status", "scene file", max_bytes=100_000)) > 20


def test_unreadable_paths_are_one_line(tmp_path):
    loop = tmp_path / "loop.json"
    loop.symlink_to(loop)  # opening it fails with ELOOP
    with pytest.raises(RaybenchError, match="loop.json: cannot read the scene file"):
        Scene.load(loop)
    with pytest.raises(RaybenchError, match="/proc/x.png: cannot write"):
        files.write_atomic("/proc/x.png", b"png")  # /proc is a folder that takes no new files


# --- 2. a planted symlink; the replaced file's mode --------------------------------------


def test_planted_symlinks_are_not_followed(tmp_path):
    """Links planted at every name the old writer would have used (and more)
    point to a victim: the victim is untouched, the output is written."""
    victim = tmp_path / "victim.txt"
    victim.write_text("precious")
    for pid in range(os.getpid() - 50, os.getpid() + 50):
        (tmp_path / f".x.png.{pid}.tmp").symlink_to(victim)
    files.write_atomic(tmp_path / "x.png", b"new")
    assert victim.read_text() == "precious"
    assert (tmp_path / "x.png").read_bytes() == b"new"
    assert len(list(tmp_path.glob(".x.png.*"))) == 100  # only the planted links, no temp file of ours


def test_replacing_keeps_the_mode_and_a_new_file_gets_the_umask(tmp_path):
    old = tmp_path / "old.png"
    old.write_bytes(b"1")
    old.chmod(0o640)
    files.write_atomic(old, b"2")
    assert stat.S_IMODE(old.stat().st_mode) == 0o640 and old.read_bytes() == b"2"
    for umask, mode in ((0o027, 0o640), (0o022, 0o644), (0o077, 0o600)):
        mask = os.umask(umask)
        try:
            files.write_atomic(tmp_path / f"new-{umask:o}.png", b"3")
        finally:
            os.umask(mask)
        assert stat.S_IMODE((tmp_path / f"new-{umask:o}.png").stat().st_mode) == mode  # 0o666 & ~umask


@pytest.mark.parametrize("when", ["just after the temporary file is made", "while the data goes to disk"])
def test_ctrl_c_during_a_write_writes_the_file_whole_then_interrupts(tmp_path, monkeypatch, when, sigint_handled):
    """SIGINT at the worst moments of an atomic write: the file is written
    whole, no temporary file is left, then KeyboardInterrupt. (Raised right
    after mkstemp, the interrupt left its file behind: the sequence's Ctrl-C
    test found one in about 10 runs.)"""
    import tempfile

    target = tmp_path / "frame.png"
    target.write_bytes(b"old")
    mkstemp, fsync = tempfile.mkstemp, os.fsync

    def interrupted(real):
        def call(*args, **kwargs):
            out = real(*args, **kwargs)
            os.kill(os.getpid(), signal.SIGINT)  # Python runs the handler at its next instruction
            return out

        return call

    if when.startswith("just after"):
        monkeypatch.setattr(tempfile, "mkstemp", interrupted(mkstemp))
    else:
        monkeypatch.setattr(os, "fsync", interrupted(fsync))
    with pytest.raises(KeyboardInterrupt):
        files.write_atomic(target, b"new")
    assert target.read_bytes() == b"new"
    assert [p.name for p in tmp_path.iterdir()] == ["frame.png"]
    assert signal.getsignal(signal.SIGINT) is signal.default_int_handler


def test_disk_full_keeps_the_old_file(tmp_path, monkeypatch):
    """ENOSPC while the data goes to disk: one line, the old file as it was, no temp file."""
    target = tmp_path / "scene.json"
    target.write_text("old")

    def full(fd):
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))

    monkeypatch.setattr(files.os, "fsync", full)
    with pytest.raises(RaybenchError, match="No space left on device") as info:
        raybench.random_spheres(5).save(target)
    assert "\n" not in str(info.value)
    assert target.read_text() == "old" and tree(tmp_path) == {"scene.json"}


def test_file_size_limit_in_a_real_process_keeps_the_old_file(tmp_path):
    """ulimit -f: the kernel refuses the write (EFBIG) part way through the PNG;
    the CLI prints one line and the old picture is kept. The compile cache
    starts empty, so its writes are refused first: the render goes on
    without it (raybench.compiled)."""
    out = tmp_path / "x.png"
    out.write_bytes(b"old picture")

    def limit():
        resource.setrlimit(resource.RLIMIT_FSIZE, (2048, 2048))

    proc = subprocess.run(
        [sys.executable, "-m", "raybench", "render", "--spheres", "200", "--size", "200x150", "--device", "cpu"]
        + ["--accel", "none", "-o", str(out)],
        preexec_fn=limit,
        capture_output=True,
        text=True,
        env=dict(
            os.environ,
            PYTHONPATH=SRC,
            NUMBA_CACHE_DIR=str(tmp_path / "numba-cache"),
            RAYBENCH_CACHE_DIR=str(tmp_path / "raybench-cache"),
        ),
        timeout=300,
        cwd=tmp_path,
    )
    assert proc.returncode == 2 and "Traceback" not in proc.stderr, proc.stderr
    assert proc.stderr.count("\n") == 1 and "x.png: cannot write" in proc.stderr, proc.stderr
    assert out.read_bytes() == b"old picture"
    assert not list(tmp_path.glob(".x.png*"))


# --- 3. no limit on what is read ------------------------------------------------------------


@pytest.mark.parametrize("args", [["render", "--scene", "/dev/zero", "--device", "cpu"], ["report", "/dev/zero"]])
def test_dev_zero_is_refused_at_once(tmp_path, args):
    """In a process of its own under a 2 GiB limit: a reader that read on
    (the old one took 24 GB) fails this test quickly, not the machine."""

    def limit():
        resource.setrlimit(resource.RLIMIT_AS, (2 * 2**30, resource.RLIM_INFINITY))

    proc = subprocess.run(
        [sys.executable, "-m", "raybench", *args],
        preexec_fn=limit,
        capture_output=True,
        text=True,
        env=dict(os.environ, PYTHONPATH=SRC),
        timeout=600,
        cwd=tmp_path,
    )
    assert proc.returncode == 2 and proc.stderr.count("\n") == 1, proc.stderr
    assert "/dev/zero: " in proc.stderr and "must be a regular file, not a device" in proc.stderr


def test_fifo_is_refused_without_waiting_for_a_writer(tmp_path):
    """In a process of its own: a reader that waited for a writer would hang (the timeout fails it)."""
    fifo = tmp_path / "pipe.json"
    os.mkfifo(fifo)
    proc = subprocess.run(
        [sys.executable, "-m", "raybench", "render", "--scene", str(fifo), "--device", "cpu"],
        capture_output=True,
        text=True,
        env=dict(os.environ, PYTHONPATH=SRC),
        timeout=600,
        cwd=tmp_path,
    )
    assert proc.returncode == 2 and proc.stderr.count("\n") == 1, proc.stderr
    assert "pipe.json: the scene file must be a regular file, not a pipe" in proc.stderr


def test_a_file_over_the_size_limit_is_refused_unread(tmp_path):
    big = tmp_path / "big.json"
    with open(big, "wb") as f:  # sparse: costs no disk
        f.truncate(files.MAX_FILE_BYTES + 1)
    with pytest.raises(RaybenchError, match="over the limit of 512 MiB"):
        Scene.load(big)
    with pytest.raises(RaybenchError, match="over the limit"):
        results.read(big)


# --- 4. memory ------------------------------------------------------------------------


@pytest.mark.parametrize(
    "args,needle",
    [
        (["--spheres", "90000000", "--size", "16x12"], "90,000,000 spheres need about"),
        (["--spheres", "3", "--size", "60000x60000"], "60000x60000 with 3 spheres needs"),
    ],
)
def test_memory_is_checked_against_the_ulimit_before_allocating(tmp_path, args, needle):
    """Under a 4 GiB address-space limit (on a machine with more free), the
    check refuses the work in one line; it used to end in a MemoryError."""

    def limit():
        resource.setrlimit(resource.RLIMIT_AS, (4 * 2**30, resource.RLIM_INFINITY))

    proc = subprocess.run(
        [sys.executable, "-m", "raybench", "render", *args, "--device", "cpu", "-o", str(tmp_path / "x.png")],
        preexec_fn=limit,
        capture_output=True,
        text=True,
        env=dict(os.environ, PYTHONPATH=SRC),
        timeout=300,
    )
    assert proc.returncode == 2 and proc.stderr.count("\n") == 1, proc.stderr
    assert needle in proc.stderr, proc.stderr
    assert not (tmp_path / "x.png").exists()


def test_host_available_bytes_honours_rlimit_as():
    import psutil

    from raybench.host import host_available_bytes

    soft, hard = resource.getrlimit(resource.RLIMIT_AS)
    used = psutil.Process().memory_info().vms
    resource.setrlimit(resource.RLIMIT_AS, (used + 2**30, hard))
    try:
        assert 0 < host_available_bytes() <= 2**30
    finally:
        resource.setrlimit(resource.RLIMIT_AS, (soft, hard))


def test_memory_error_anywhere_is_one_line(capsys, monkeypatch):
    def exhausted(*args, **kwargs):
        raise MemoryError

    monkeypatch.setattr(raybench.scene, "random_spheres", exhausted)
    one_line(capsys, ["render", "--spheres", "5", "--size", "8x6", "--device", "cpu"], "out of memory")


# --- 5. hand-edited results files -------------------------------------------------------------


@pytest.mark.parametrize(
    "change,needle",
    [
        (set_at(["run", "machine", "cpu"], "fast"), "run.machine.cpu: must be an object, got 'fast'"),
        (set_at(["run", "machine", "gpus", 0], "H100"), "run.machine.gpus[0]: must be an object"),
        (set_at(["run", "settings"], "quick"), "run.settings: must be an object"),
        (set_at(["test"], [1]), "test: must be a whole number"),
        (set_at(["run", "id"], ["a"]), "run.id: must be one line of text"),
        (set_at(["width"], True), "width: must be a whole number from 1 to 65536, got True"),
        (set_at(["spheres"], -5), "spheres: must be a whole number from 0"),
        (set_at(["frame_ms", "median"], 1e308), "frame_ms.median: must be a time from 1e-09 to 1e+15"),
        # a denormal once printed table cells of 3,600 characters
        (set_at(["frame_ms", "median"], 5e-324), "frame_ms.median: must be a time from 1e-09 to 1e+15, got 5e-324"),
        # options the report reads: as strict as its reader (each was a traceback, or a changed report)
        (set_at(["options", "workers"], "two"), "options.workers: must be a whole number from 1 to 100000"),
        (set_at(["options", "workers"], 0), "options.workers: must be a whole number from 1 to 100000, got 0"),
        (set_at(["options", "job"], ["frame"]), "options.job: must be one of frame, sequence"),
        (set_at(["options", "build"], 3), "options.build: must be one of host, gpu, got 3"),
        (set_at(["options", "label"], ["x"]), "options.label: must be a short text"),
        (set_at(["options", "threads"], "many"), "options.threads: must be a whole number from 1"),
        (set_at(["run", "label"], "a <img src=x>"), "run.label: must be a name"),
        (set_at(["device"], "tpu"), "device: must be one of cpu, cuda, wgpu"),
    ],
)
def test_hand_edited_results_are_one_line_and_leave_no_folder(capsys, tmp_path, change, needle):
    records = [rec("thesis", "cpu", 100, 5.0), rec("thesis", "cuda", 100, 1.0)]
    records[1]["run"]["settings"] = {"quick": True}
    change(records[1])
    path = write(tmp_path / "r.jsonl", records)
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # 1e308 used to print 28 overflow warnings
        one_line(capsys, ["report", path, "-o", tmp_path / "rep"], "r.jsonl: line 2: " + needle)
    assert not (tmp_path / "rep").exists()


def test_a_results_file_with_a_bom_is_refused_naming_the_bom(capsys, tmp_path):
    path = write(tmp_path / "r.jsonl", [rec("thesis", "cpu", 100, 5.0)])
    path.write_bytes(b"\xef\xbb\xbf" + path.read_bytes())
    one_line(capsys, ["report", path, "-o", tmp_path / "rep"], "r.jsonl", "byte-order mark (BOM)")
    assert not (tmp_path / "rep").exists()


def test_a_folder_of_results_skips_foreign_files_one_line_each(capsys, tmp_path):
    folder = tmp_path / "runs"
    write(folder / "a.jsonl", [rec("thesis", "cpu", 100, 5.0)])
    write(folder / "deeper" / "b.jsonl", [rec("thesis", "cuda", 100, 1.0)])
    (folder / "foreign.jsonl").write_text('{"name": "another tool"}\n')
    (folder / "deeper" / "empty.jsonl").write_text("")
    (folder / "notes.txt").write_text("not looked at")
    assert run(["report", str(folder), "-o", str(tmp_path / "rep")]) == 0
    out, err = capsys.readouterr()
    assert err.splitlines() == [
        f"raybench: warning: skipped {folder / 'deeper' / 'empty.jsonl'}: holds no results",
        f"raybench: warning: skipped {folder / 'foreign.jsonl'}: line 1 is not a raybench result "
        "(format 'raybench-results' expected)",
    ]
    text = (tmp_path / "rep" / "report.md").read_text()
    assert "a.jsonl" in text and "b.jsonl" in text and "Synthetic GPU" in text
    # a file named is still read or refused, never skipped
    one_line(capsys, ["report", folder / "foreign.jsonl", "-o", tmp_path / "rep2"], "not a raybench result")
    (folder / "a.jsonl").unlink()
    (folder / "deeper" / "b.jsonl").unlink()
    assert run(["report", str(folder), "-o", str(tmp_path / "rep3")]) == 2
    assert capsys.readouterr().err.endswith("no raybench results among the files found\n")


def test_the_report_is_built_aside_and_renamed_into_place(capsys, tmp_path, monkeypatch):
    """Stopped half-way (Ctrl-C, a crash, a full disk) it leaves no report folder, and no
    earlier report is touched; a folder holding anything but a report is not replaced."""
    records = [rec("thesis", d, n, 5.0 + n / 100) for d in ("cpu", "cuda") for n in (100, 200, 300)]
    path = write(tmp_path / "r.jsonl", records)
    from raybench.bench.report import charts, markdown, markdown_blocks

    drawn = []

    def stopped(*args, **kwargs):
        drawn.append(1)
        if len(drawn) == 2:  # after the first chart is on disk
            raise KeyboardInterrupt
        return real(*args, **kwargs)

    real = charts.plot_thesis
    monkeypatch.setattr(charts, "plot_thesis", stopped)
    assert run(["report", str(path), "-o", str(tmp_path / "rep")]) == 130
    assert not (tmp_path / "rep").exists()
    assert tree(tmp_path) == {"r.jsonl"}  # nor its staging folder
    monkeypatch.setattr(charts, "plot_thesis", real)
    assert run(["report", str(path), "-o", str(tmp_path / "rep")]) == 0
    before = {p.name: p.read_bytes() for p in (tmp_path / "rep").iterdir()}
    drawn.clear()
    monkeypatch.setattr(charts, "plot_thesis", stopped)

    def full_disk(path, data):
        raise RaybenchError(f"{path}: cannot write (No space left on device); nothing was changed")

    monkeypatch.setattr(markdown, "write_atomic", full_disk)
    monkeypatch.setattr(markdown_blocks, "write_atomic", full_disk)  # the charts' writes
    capsys.readouterr()
    line = one_line(capsys, ["report", path, "-o", tmp_path / "rep"], "No space left on device")
    assert f"{tmp_path / 'rep'}/" in line and ".partial" not in line
    assert {p.name: p.read_bytes() for p in (tmp_path / "rep").iterdir()} == before
    assert not [p for p in tmp_path.iterdir() if p.name.startswith(".")]
    capsys.readouterr()
    (tmp_path / "mine").mkdir()
    (tmp_path / "mine" / "thesis.tex").write_text("mine")
    one_line(capsys, ["report", path, "-o", tmp_path / "mine"], "holds 'thesis.tex'", "choose a new or empty")
    assert tree(tmp_path / "mine") == {"thesis.tex"}


def test_the_results_file_name_is_escaped_in_the_report(tmp_path):
    name = "a`b <img src=x onerror=alert(1)> [x](y).jsonl"
    path = write(tmp_path / name, [rec("thesis", "cpu", 100, 5.0)])
    text = report.write_report([path], tmp_path / "rep").read_text()
    sources = text.split("## Sources", 1)[1]
    assert "<img" not in sources and "`" not in sources and "[x](y)" not in sources
    assert "onerror=alert(1)" in sources  # shown, inert


def test_duplicate_keys_are_refused(capsys, tmp_path):
    scene = tmp_path / "s.json"
    scene.write_text(
        '{"format": "raybench-scene", "version": 1, "spheres": '
        '[{"center": [0, 0, 5], "radius": -1, "radius": 1, "color": [1, 0, 0]}]}'
    )
    one_line(capsys, ["render", "--scene", scene, "--size", "8x6", "--device", "cpu"], 'key "radius" appears twice')
    path = write(tmp_path / "r.jsonl", [rec("thesis", "cpu", 100, 5.0)])
    line = path.read_text().replace('"device":"cpu"', '"device":"cpu","device":"cuda"')
    path.write_text(line)
    one_line(capsys, ["report", path], "r.jsonl: line 1", 'key "device" appears twice')


def test_reading_results_is_linear(tmp_path):
    """Sixteen times the lines take 17-23 times as long; the old reader, which
    sliced the list of the lines left for every line, took 106 times. The
    two sizes are read in turn and timed in this process's CPU time, not the
    wall clock, so that a CI machine's other test process (Numba's threads
    too) counts as little as it can: with two busy loops beside it on the
    2-core machine the ratio was 21. A wall-clock version of this test,
    4 times the lines against a bound of 8, failed once in CI at 8.9."""
    line = json.dumps({"format": "raybench-results", "version": 1, **rec("thesis", "cpu", 100, 5.0)})
    paths = {}
    for n in (5_000, 80_000):
        paths[n] = tmp_path / f"{n}.jsonl"
        paths[n].write_text((line + "\n") * n)
    best = dict.fromkeys(paths, float("inf"))
    for _ in range(2):
        for n, path in paths.items():
            start = time.process_time()
            assert len(results.read(path)) == n
            best[n] = min(best[n], time.process_time() - start)
    assert best[80_000] / best[5_000] < 48, best


# --- 6. the Python API -------------------------------------------------------------------------

GOOD_C, GOOD_R, GOOD_K = [[0, 0, 5], [1, 0, 6]], [0.5, 0.5], [[1, 0, 0], [0, 1, 0]]


@pytest.mark.parametrize(
    "centers,radii,colors,needle",
    [
        (np.zeros((3, 2)), [1, 1, 1], np.zeros((3, 3)), "centers must have shape (n, 3), got (3, 2)"),
        ([0, 0, 5, 1, 0, 6], GOOD_R, GOOD_K, "centers must have shape (n, 3), got (6,)"),
        (GOOD_C, [0.5 + 1j, 0.5], GOOD_K, "radii must be real numbers"),
        (GOOD_C, GOOD_R, [[True, False, True], [True, True, False]], "colors must be real numbers"),
        (GOOD_C, ["a", "b"], GOOD_K, "radii must be real numbers"),
        ([[0, 0, 5], [1, 0]], GOOD_R, GOOD_K, "centers must be an array"),
        (GOOD_C, [[0.5], [0.5]], GOOD_K, "radii must have shape (n,)"),
    ],
)
def test_scene_arrays_are_checked_not_reshaped(centers, radii, colors, needle):
    with pytest.raises(RaybenchError) as info:
        Scene(centers, radii, colors)
    assert needle in str(info.value) and "\n" not in str(info.value)


def test_scene_accepts_numpy_numbers_of_any_width():
    scene = Scene(np.array(GOOD_C, np.int16), np.array(GOOD_R, np.float32), np.array(GOOD_K, np.uint8))
    assert len(scene) == 2 and scene.spheres.dtype == np.float32
    assert len(Scene([], [], [])) == 0


def test_head_refuses_negative_and_takes_numpy_integers():
    scene = raybench.random_spheres(5)
    with pytest.raises(RaybenchError, match=r"head: n must be an integer from 0 to 5 \(the spheres\), got -1$"):
        scene.head(-1)
    with pytest.raises(RaybenchError, match="got 6"):
        scene.head(6)
    assert len(scene.head(np.int64(3))) == 3
    assert np.array_equal(scene.head(np.int32(2)).spheres, scene.spheres[:, :2])


def test_render_takes_numpy_integers_and_refuses_a_bad_camera():
    scene = raybench.random_spheres(4)
    a = raybench.render(scene, width=np.int64(12), height=np.uint16(8), device="cpu")
    b = raybench.render(scene, width=12, height=8, device="cpu")
    assert np.array_equal(a.image, b.image) and a.image.shape == (8, 12, 3)
    for camera in ("abc", {"position": [0, 0, 0]}, 3):
        with pytest.raises(RaybenchError, match="camera: must be a raybench.Camera or None"):
            raybench.render(scene, camera, width=8, height=6, device="cpu")
    with pytest.raises(RaybenchError, match="width must be an integer"):
        raybench.render(scene, width=np.float64(8), height=6, device="cpu")


@pytest.mark.parametrize(
    "kwargs,needle",
    [
        ({"position": "123"}, "camera.position: must be 3 numbers"),
        ({"up": [0, 1 + 1j, 0]}, "camera.up: must be 3 numbers"),
        ({"up": np.array([0, 1 + 1j, 0])}, "camera.up: must be 3 numbers"),
        ({"fov_deg": "60"}, "camera.fov_deg: must be a number"),
        ({"fov_deg": np.float64(200.0)}, "got 200.0"),
    ],
)
def test_camera_refuses_text_and_complex(kwargs, needle):
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # no ComplexWarning on the way
        with pytest.raises(RaybenchError) as info:
            Camera(**kwargs)
    assert needle in str(info.value) and "np." not in str(info.value)


# --- 7. the small ones ------------------------------------------------------------------------


def test_messages_show_plain_numbers():
    with pytest.raises(RaybenchError) as info:
        Scene([[0, 0, 5]], np.array([-1.0]), [[1, 0, 0]])
    assert str(info.value) == "spheres[0].radius: must be > 0, got -1.0"
    with pytest.raises(RaybenchError) as info:
        raybench.random_spheres(np.int64(-3))
    assert "got -3" in str(info.value) and "np." not in str(info.value)


def test_radius_zero_in_float32_says_why():
    with pytest.raises(RaybenchError) as info:
        Scene([[0, 0, 5]], [1e-50], [[1, 0, 0]])
    assert "got 1e-50 (0 in float32; the smallest radius is 1.4013e-45)" in str(info.value)


def test_bench_interrupted_before_the_first_point_leaves_nothing(capsys, tmp_path, monkeypatch):
    from raybench.bench import runner

    def interrupted(*args, **kwargs):
        raise KeyboardInterrupt

    monkeypatch.setattr(runner, "run", interrupted)
    before = tree(tmp_path)
    with pytest.raises(SystemExit) as exit_:
        run(["bench", "--quick", "--device", "cpu", "--out", str(tmp_path / "out"), "--suite", "thesis"])
    out, err = capsys.readouterr()
    assert exit_.value.code == 130 and "no results were written" in err and "raybench report" not in err, err
    assert tree(tmp_path) == before


def test_render_to_an_unwritable_folder_fails_before_the_render(capsys, monkeypatch):
    """/proc takes no new files, though os.access says root may write there."""
    render_mod = sys.modules["raybench.render"]  # raybench.render is also the function

    def never(*args, **kwargs):
        raise AssertionError("rendered before checking the output")

    monkeypatch.setattr(render_mod, "render", never)
    one_line(capsys, ["render", "--spheres", "3", "--size", "8x6", "--device", "cpu", "-o", "/proc/x.png"], "x.png")


def test_report_escapes_text_from_results_files(tmp_path):
    hostile = machine()
    # "$\\notacommand$" would stop matplotlib's mathematics in a plot's title
    hostile["cpu"]["model"] = (
        "<img src=x onerror=alert(1)> ![pwned](http://e.x/a.png) [link](http://e.x) $\\notacommand$"
    )
    hostile["gpus"][0]["name"] = "**Hostile** `code` <script>"
    hostile["gpus"][0]["driver"] = "1 | 2"
    records = [rec("thesis", "cpu", n, 5.0 + n, mach=hostile) for n in (100, 200, 300)]
    records += [rec("thesis", "cuda", n, 1.0 + n / 10, mach=hostile) for n in (100, 200, 300)]
    text = report.write_report([write(tmp_path / "r.jsonl", records)], tmp_path / "rep").read_text()
    for raw in ("<img", "<script", "![pwned]", "[link](", "**Hostile**", "`code`"):
        assert not re.search(r"(?<!\\)" + re.escape(raw), text), raw  # escaped, whichever way
    for word in ("onerror=alert", "pwned", "Hostile", "code", "notacommand"):
        assert word in text, word  # and still shown


# --- faults during work -------------------------------------------------------------------------

WRITER = """
import sys
from raybench.bench.results import ResultsWriter
record = {rec}
record["series"] = {{"spheres": [1] * 20000, "frame_ms": [1.5] * 20000}}
with ResultsWriter(sys.argv[1]) as w:
    while True:
        w.write(record)
"""


def test_results_torn_by_sigkill_keep_every_whole_record(tmp_path):
    """A writer killed with SIGKILL mid-run: every whole line is read, a torn
    last line is skipped with one warning. The kill lands wherever it lands;
    a torn line is then also made by cutting the file inside its last record,
    as a kill during the write would leave it."""
    record = rec("test7", "cpu", 1000, 2.0, test=7)
    path = tmp_path / "r.jsonl"
    proc = subprocess.Popen(
        [sys.executable, "-c", WRITER.format(rec=repr(record)), str(path)], env=dict(os.environ, PYTHONPATH=SRC)
    )
    try:
        deadline = time.monotonic() + 60
        while (not path.exists() or path.stat().st_size < 2_000_000) and time.monotonic() < deadline:
            time.sleep(0.05)
    finally:
        os.kill(proc.pid, signal.SIGKILL)
        proc.wait()
    data = path.read_bytes()
    complete = data[: data.rfind(b"\n") + 1]
    whole = complete.count(b"\n")
    assert whole >= 5
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        assert len(results.read(path)) == whole
    assert len(caught) == (0 if data == complete else 1)
    line = complete[: complete.index(b"\n")]
    path.write_bytes(complete + line[: len(line) // 2])
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        assert len(results.read(path)) == whole
        machines, notes = report.load([path])
    assert sum(len(v) for v in machines.values()) == 1  # the same point every time: the later record kept
    assert [str(w.message) for w in caught] == [
        f"{path}: line {whole + 1} is cut short (an interrupted run?); skipped it"
    ] * 2
    assert any("cut short" in n for n in notes)


def test_results_writer_on_a_full_disk_keeps_the_records_before(tmp_path, monkeypatch):
    """The disk fills while a record is written: one line, the part of it
    that reached the disk cut off again, the records before it read back."""
    real_write = os.write

    def full(fd, data):
        real_write(fd, bytes(data[: len(data) // 3]))  # part of the line reached the disk
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))

    path = tmp_path / "r.jsonl"
    writer = results.ResultsWriter(path)
    writer.write(rec("thesis", "cpu", 100, 5.0))
    monkeypatch.setattr(files.os, "write", full)
    with pytest.raises(RaybenchError, match="No space left on device.*the 1 records before this one are kept"):
        writer.write(rec("thesis", "cpu", 200, 5.0))
    monkeypatch.undo()
    writer.close()
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # no half line left to warn of
        assert [r["spheres"] for r in results.read(path)] == [100]


def test_results_writer_on_a_full_disk_leaves_no_empty_file(tmp_path, monkeypatch):
    """The disk is full at the first record: one line, and no results file
    (it used to be left empty, 0 bytes, while bench said nothing was written)."""

    def full(fd):
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))

    path = tmp_path / "out" / "r.jsonl"
    writer = results.ResultsWriter(path)
    monkeypatch.setattr(files.os, "fsync", full)
    with pytest.raises(RaybenchError, match="No space left on device.*nothing was changed"):
        writer.write(rec("thesis", "cpu", 100, 5.0))
    writer.close()
    assert not path.exists() and list(tmp_path.iterdir()) == []  # nor the folder made for it


def test_bench_on_a_full_disk_leaves_no_results_file(capsys, tmp_path, monkeypatch):
    """bench's first record meets a full disk: one line that says nothing
    was written, and nothing is (the results file was left empty, 0 bytes)."""
    from raybench.bench import runner

    def full(fd):
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))

    def one_point(points, writer, *args, **kwargs):
        monkeypatch.setattr(files.os, "fsync", full)
        writer.write(rec("thesis", "cpu", 100, 5.0))

    monkeypatch.setattr(runner, "run", one_point)
    before = tree(tmp_path)
    line = one_line(capsys, ["bench", "--quick", "--device", "cpu", "--out", tmp_path / "out", "--suite", "thesis"],
                    "No space left on device", "no results were written")  # fmt: skip
    assert "results-" in line and tree(tmp_path) == before


# --- found by the fuzzer ----------------------------------------------------------------------


def test_a_key_or_file_name_with_a_line_break_is_still_one_line(capsys, tmp_path):
    """Seed 2 of the fuzzer: an unknown key "\\r" made the error two lines."""
    (tmp_path / "s.json").write_text(json.dumps(scene_doc(0) | {"\r": None}))
    line = one_line(capsys, ["render", "--scene", "s.json", "--device", "cpu"], "unknown field")
    assert 's.json: "\\r": unknown field' in line, line  # the key, quoted and escaped
    one_line(capsys, ["render", "--scene", "a\nb\u2028c.json", "--device", "cpu"], "a\\nb\\u2028c.json: no such")


@pytest.mark.parametrize(
    "options,needle",
    [
        ({"accel": np.int64(7)}, "accel: must be one of bvh, none, got 7"),
        ({"kernel": np.int64(7)}, "kernel: must be one of fast, simple, got 7"),
        ({"threads": np.int8(-1)}, "threads: must be an integer from 1 to"),
    ],
)
def test_option_values_are_shown_as_plain_numbers(options, needle):
    """Seed 1 of the fuzzer: these said np.int64(7)."""
    with pytest.raises(RaybenchError) as info:
        raybench.render(raybench.random_spheres(3), width=8, height=6, device="cpu", **options)
    assert needle in str(info.value) and "np." not in str(info.value), info.value


@pytest.mark.parametrize("version", [1, 2])
def test_cgroup_memory_limit_is_read(tmp_path, version):
    """A container's limit, as cgroup v1 and v2 show it (a fake /sys tree):
    the limit less the usage; no limit where it says "max" or a huge number."""
    from raybench.host import _cgroup_headroom

    proc = tmp_path / "cgroup"
    proc.write_text("0::/box\n" if version == 2 else "4:memory:/box\n1:cpu:/\n")
    folder = tmp_path / ("box" if version == 2 else "memory/box")
    folder.mkdir(parents=True)
    limit, usage = (
        ("memory.max", "memory.current") if version == 2 else ("memory.limit_in_bytes", "memory.usage_in_bytes")
    )
    (folder / limit).write_text(f"{3 * 2**30}\n")
    (folder / usage).write_text(f"{2**30}\n")
    assert _cgroup_headroom(str(tmp_path), str(proc)) == 2 * 2**30
    (folder / limit).write_text("max\n" if version == 2 else "9223372036854771712\n")
    assert _cgroup_headroom(str(tmp_path), str(proc)) is None
    (folder / usage).unlink()
    assert _cgroup_headroom(str(tmp_path), str(proc)) is None  # unreadable: no limit known


# --- a device failing in the middle of a run --------------------------------------------------


def _device_errors():
    """Errors as the device libraries raise them: wgpu's, and numba-cuda's driver's."""
    import wgpu
    from numba.cuda.cudadrv import driver

    yield wgpu.GPUError("Parent device is lost")
    yield driver.CudaAPIError(700, "Call to cuLaunchKernel results in CUDA_ERROR_ILLEGAL_ADDRESS")


@pytest.mark.parametrize("error", list(_device_errors()), ids=lambda e: type(e).__name__)
def test_bench_device_failing_mid_run_keeps_the_finished_points(capsys, tmp_path, monkeypatch, error):
    from raybench.bench import runner

    measure, calls = runner.measure, []

    def failing_second(*args, **kwargs):
        calls.append(1)
        if len(calls) == 2:
            raise error
        return measure(*args, **kwargs)

    monkeypatch.setattr(runner, "measure", failing_second)
    out_dir = tmp_path / "out"
    argv = ["bench", "--quick", "--device", "cpu", "--suite", "thesis", "--accel", "bvh", "--duration", "0.05"]
    code = run([*argv, "--out", str(out_dir), "--no-report"])
    out, err = capsys.readouterr()
    assert code == 2 and err.count("\n") == 1 and "Traceback" not in err, err
    assert "the device failed" in err and type(error).__name__ in err and "1 finished points are in" in err, err
    (path,) = out_dir.glob("results-*.jsonl")
    (record,) = results.read(path)
    assert record["spheres"] == 100


@pytest.mark.parametrize("error", list(_device_errors()), ids=lambda e: type(e).__name__)
def test_render_device_failing_is_one_line_and_writes_nothing(capsys, tmp_path, monkeypatch, error):
    render_mod = sys.modules["raybench.render"]

    def failing(*args, **kwargs):
        raise error

    monkeypatch.setattr(render_mod, "render", failing)
    before = tree(tmp_path)
    code = run(["render", "--spheres", "3", "--size", "8x6", "--device", "cpu", "-o", str(tmp_path / "x.png")])
    out, err = capsys.readouterr()
    assert code == 2 and err.count("\n") == 1 and "the device failed" in err and "Traceback" not in err, err
    assert tree(tmp_path) == before


def test_a_bug_is_not_told_as_a_device_failure(monkeypatch, tmp_path):
    """Only the device libraries' errors become one line: raybench's own bugs keep their traceback."""
    render_mod = sys.modules["raybench.render"]

    def buggy(*args, **kwargs):
        raise IndexError("a bug")

    monkeypatch.setattr(render_mod, "render", buggy)
    with pytest.raises(IndexError):
        run(["render", "--spheres", "3", "--size", "8x6", "--device", "cpu", "-o", str(tmp_path / "x.png")])
