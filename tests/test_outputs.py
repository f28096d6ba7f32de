"""Every output raybench writes (-o, --gif, a sequence's frames, a results
file, Scene.save) goes through one opener, raybench.files: only a regular
file is written or replaced; a FIFO, a device, a socket or a folder at the
path is refused in one line and left as it was; a symlink is replaced, never
followed, and the new file's mode is the umask's, never the link target's;
a name the file system cannot hold and a place where nothing can be made
are one line and exit 2, before any work."""

from __future__ import annotations

import errno
import os
import socket
import stat
import sys
from pathlib import Path

import pytest

import raybench
from raybench import RaybenchError, files
from raybench.bench import results
from raybench.cli import run

ERROR = "raybench: error: "
RENDER = ["render", "--spheres", "3", "--size", "8x6", "--device", "cpu"]


@pytest.fixture(autouse=True)
def in_tmp(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)


def one_line(capsys, args, *needles) -> str:
    """The CLI in-process: exit code 2, one stderr line naming every needle, no traceback."""
    got = run([str(a) for a in args])
    out, err = capsys.readouterr()
    assert "Traceback" not in out + err and got == 2, (got, out, err)
    lines = err.splitlines()
    assert len(lines) == 1 and lines[0].startswith(ERROR), err
    for needle in needles:
        assert needle in lines[0], (needle, lines[0])
    return lines[0]


def plant(path: Path, kind: str) -> None:
    """Something that is not a regular file at path."""
    if kind == "fifo":
        os.mkfifo(path)
    elif kind == "socket":
        sock = socket.socket(socket.AF_UNIX)
        sock.bind(str(path))
        sock.close()  # the socket file stays
    elif kind == "device":
        try:
            os.mknod(path, 0o666 | stat.S_IFCHR, os.makedev(1, 3))  # as /dev/null
        except PermissionError:
            pytest.skip("making a device node needs root (CI runs as root)")
    else:
        path.mkdir()


def identity(path: Path) -> tuple:
    info = os.lstat(path)
    return info.st_ino, stat.S_IFMT(info.st_mode), info.st_mtime_ns


KINDS = ["fifo", "socket", "device", "folder"]
NEEDLE = {"fifo": "is a pipe", "socket": "is a socket", "device": "is a device", "folder": "is a folder"}


@pytest.mark.parametrize("kind", KINDS)
def test_a_non_regular_file_at_an_output_is_refused_and_left(tmp_path, capsys, kind):
    """-o, --gif, Frame.save, Scene.save and the results writer: one line,
    nothing written, the thing at the path the same inode it was."""
    frame = raybench.render(raybench.random_spheres(2), width=8, height=6, device="cpu")

    def refused(write):
        def call(path):
            with pytest.raises(RaybenchError, match=NEEDLE[kind]):
                write(path)

        return call

    for name, write in [
        ("a.png", lambda p: one_line(capsys, [*RENDER, "-o", p], str(p), NEEDLE[kind])),
        ("e.gif", lambda p: one_line(capsys, [*RENDER, "--path", "orbit", "-o", "f", "--gif", p], NEEDLE[kind])),
        ("b.png", refused(frame.save)),
        ("c.json", refused(raybench.random_spheres(2).save)),
        ("d.jsonl", refused(results.ResultsWriter)),
    ]:
        path = tmp_path / name
        plant(path, kind)
        before = identity(path)
        write(path)
        assert identity(path) == before, name
    assert not [p for p in tmp_path.iterdir() if p.name.startswith(".")]  # no temporary file left


def test_something_planted_between_the_check_and_the_rename_is_not_replaced(tmp_path, monkeypatch):
    """A FIFO made at the path while the data is written (after the first
    look) is still found before the rename."""
    path = tmp_path / "x.png"
    fsync = os.fsync

    def plant_then_sync(fd):
        if not path.exists():
            os.mkfifo(path)
        return fsync(fd)

    monkeypatch.setattr(files.os, "fsync", plant_then_sync)
    with pytest.raises(RaybenchError, match="is a pipe"):
        files.write_atomic(path, b"png")
    assert stat.S_ISFIFO(os.lstat(path).st_mode) and sorted(os.listdir(tmp_path)) == ["x.png"]


def test_a_symlink_is_replaced_with_the_umasks_mode_never_the_targets(tmp_path, rng):
    """A link at the output path, to a file of a random mode (0666 among
    them) or to /dev/null: the link is replaced by a regular file whose mode
    is 0666 less the umask; the target keeps its bytes and its mode."""
    for i in range(4):
        target = tmp_path / f"target-{i}"
        target.write_bytes(b"precious")
        target_mode = int(rng.choice([0o666, 0o777, 0o644, 0o600, 0o640]))
        target.chmod(target_mode)
        umask = int(rng.choice([0o022, 0o027, 0o077, 0o002]))
        for link_to in (target, Path("/dev/null")):
            link = tmp_path / f"out-{i}-{link_to.name}.png"
            link.symlink_to(link_to)
            old = os.umask(umask)
            try:
                files.write_atomic(link, b"new")
            finally:
                os.umask(old)
            info = os.lstat(link)
            assert stat.S_ISREG(info.st_mode) and stat.S_IMODE(info.st_mode) == 0o666 & ~umask, (oct(umask), link)
            assert link.read_bytes() == b"new"
        assert target.read_bytes() == b"precious" and stat.S_IMODE(target.stat().st_mode) == target_mode
    assert stat.S_ISCHR(os.stat("/dev/null").st_mode)


def test_a_name_over_255_bytes_is_one_line_before_the_work(capsys, rng, monkeypatch):
    """-o and --gif names too long for the file system (counted in bytes:
    some of them fewer than 255 characters), and --path's folder."""
    traced = []
    monkeypatch.setattr(sys.modules["raybench.render"], "render", lambda *a, **k: traced.append(1))
    for _ in range(3):
        stem = "é" * int(rng.integers(128, 200)) if rng.uniform() < 0.5 else "a" * int(rng.integers(256, 400))
        one_line(capsys, [*RENDER, "-o", stem + ".png"], "File name too long")
        one_line(capsys, [*RENDER, "--path", "orbit", "-o", stem], "File name too long")
        one_line(capsys, [*RENDER, "--path", "orbit", "-o", "f", "--gif", stem + ".gif"], "File name too long")
    assert traced == [] and os.listdir(".") == []


@pytest.mark.parametrize("error", [errno.EROFS, errno.EACCES, errno.ENOSPC])
def test_a_sequence_folder_that_cannot_be_made_is_one_line(capsys, monkeypatch, error):
    """--path ... -o DIR where DIR cannot be made (a read-only file system,
    no permission, a full disk; root passes permission checks, so the
    kernel's answer is stood in for): one line, exit 2, no cluster started."""

    def refused(self, *args, **kwargs):
        raise OSError(error, os.strerror(error), str(self))

    monkeypatch.setattr(Path, "mkdir", refused)
    one_line(capsys, [*RENDER, "--path", "orbit", "-o", "frames"], "-o frames: cannot make the folder",
             os.strerror(error))  # fmt: skip


def test_a_real_place_that_takes_no_folder_is_one_line(capsys):
    """/proc takes no new folder, whoever asks (root included)."""
    one_line(capsys, [*RENDER, "--path", "orbit", "-o", "/proc/raybench-frames"], "cannot make the folder")
    assert not os.path.exists("/proc/raybench-frames")


def test_a_file_where_the_sequence_folder_should_be_is_one_line(capsys, tmp_path):
    (tmp_path / "frames").write_bytes(b"x")
    one_line(capsys, [*RENDER, "--path", "orbit", "-o", "frames"], "is a file")


def test_results_are_appended_to_a_regular_file_only(tmp_path, rng):
    """An existing results file is appended to, whole records; a link put
    in its place later is not followed."""
    path = tmp_path / "r.jsonl"
    records = [{"suite": "thesis", "n": int(n)} for n in rng.integers(0, 1000, 3)]
    with results.ResultsWriter(path) as writer:
        writer.write(records[0])
    with results.ResultsWriter(path) as writer:
        writer.write(records[1])
    lines = path.read_text().splitlines()
    assert len(lines) == 2 and all(line.startswith('{"format":"raybench-results"') for line in lines)
    victim = tmp_path / "victim"
    victim.write_text("precious")
    appended = files.Appended(tmp_path / "s.jsonl")
    appended.append(b"1\n")
    os.unlink(tmp_path / "s.jsonl")
    os.symlink(victim, tmp_path / "s.jsonl")
    appended.append(b"2\n")  # into the file it made, now unlinked: never the link's target
    appended.close()
    assert victim.read_text() == "precious"
    again = files.Appended(tmp_path / "s.jsonl")
    os.unlink(tmp_path / "s.jsonl")
    os.mkfifo(tmp_path / "s.jsonl")
    with pytest.raises(RaybenchError, match="is a pipe"):
        again.append(b"3\n")
    assert stat.S_ISFIFO(os.lstat(tmp_path / "s.jsonl").st_mode)
