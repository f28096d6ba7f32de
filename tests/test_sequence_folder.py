"""A sequence's folder is checked before anything is traced (raybench.sequence,
issue 29): a garbage file, a folder, a symlink or a FIFO where a frame
belongs, a frame of another size, or frames of another sequence (its
marker's scene, cameras, shading) are one line and exit 2, with no worker
started; a GIF of raybench's own large frames is not refused by Pillow's
guard against decompression bombs, which still holds for other files."""

from __future__ import annotations

import json
import os
import warnings
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

import raybench
import raybench.cli.render as cli_render
from raybench import Camera, RaybenchError, camera_path, sequence
from raybench.cli import run
from raybench.gif import MAX_SIDE, write_gif
from raybench.render import png_bytes

W, H, FRAMES = 24, 16, 4


@pytest.fixture(autouse=True)
def in_tmp(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)


@pytest.fixture
def no_cluster(monkeypatch):
    """open_cluster recorded, never started: every case here is refused before it."""
    opened = []
    monkeypatch.setattr(cli_render, "open_cluster", lambda *a, **k: opened.append(a) or pytest.fail("cluster"))
    return opened


def picture(rng, width=W, height=H) -> bytes:
    return png_bytes(rng.integers(0, 256, (height, width, 3), dtype=np.uint8))


def contents(folder: Path) -> dict:
    return {p.name: (os.lstat(p).st_ino, os.lstat(p).st_mtime_ns) for p in folder.iterdir()}


def link_to_a_frame(path: Path, rng) -> None:
    """A symlink to a good frame of this size, elsewhere: not a frame of the folder's own."""
    (path.parent / "elsewhere.png").write_bytes(picture(rng))
    path.symlink_to("elsewhere.png")


PLANTS = {
    "garbage": lambda path, rng: path.write_bytes(rng.bytes(int(rng.integers(0, 4000)))),
    "text": lambda path, rng: path.write_text("not a picture\n"),
    "folder": lambda path, rng: path.mkdir(),
    "symlink": lambda path, rng: link_to_a_frame(path, rng),
    "fifo": lambda path, rng: os.mkfifo(path),
    "another size": lambda path, rng: path.write_bytes(picture(rng, W + int(rng.integers(1, 9)), H)),
}
NEEDLE = {"garbage": "is not a PNG image", "text": "is not a PNG image", "folder": "is a folder, not a frame",
          "symlink": "is a symlink, not a frame", "fifo": "is a pipe, not a frame",
          "another size": f"this sequence's frames {W}x{H}"}  # fmt: skip


@pytest.mark.parametrize("kind", PLANTS)
def test_anything_but_a_frame_where_one_belongs_is_one_line_before_tracing(capsys, tmp_path, rng, kind, no_cluster):
    frames = tmp_path / "frames"
    frames.mkdir()
    n = int(rng.integers(FRAMES))
    PLANTS[kind](sequence.frame_path(frames, n), rng)
    for k in range(FRAMES):  # the frames around it are good ones of this size
        if k != n and rng.uniform() < 0.5:
            sequence.frame_path(frames, k).write_bytes(picture(rng))
    before = contents(frames)
    args = ["render", "--spheres", "3", "--size", f"{W}x{H}", "--path", "orbit", "--frames", str(FRAMES),
            "-o", "frames", "--gif", "out.gif"]  # fmt: skip
    assert run(args) == 2
    out, err = capsys.readouterr()
    assert err.count("\n") == 1 and "Traceback" not in err, err
    assert f"frame_{n:05d}.png" in err and NEEDLE[kind] in err, err
    assert contents(frames) == before and not no_cluster and not (tmp_path / "out.gif").exists()


def marker_of(rng, n=None, size=(W, H), shading="thesis", frames=FRAMES, seed=None):
    scene = raybench.random_spheres(n or 5, seed=int(rng.integers(2**31)) if seed is None else seed, materials=True)
    return scene, sequence.identity(scene, camera_path.orbit(Camera(), frames), *size, shading)


def test_frames_of_another_sequence_are_refused_by_the_marker(tmp_path, rng):
    """Frames of this size but another scene, camera path or shading: one line
    naming what differs; the same sequence resumes (only the missing
    frames to trace); a folder without frames takes the new marker."""
    seed = int(rng.integers(2**31))
    _, mine = marker_of(rng, seed=seed)
    assert sequence.prepare(tmp_path, mine) == list(range(FRAMES))  # empty: all to trace, and marked
    assert json.loads((tmp_path / sequence.MARKER).read_text()) == mine
    kept = sorted(rng.choice(FRAMES, int(rng.integers(1, FRAMES)), replace=False).tolist())
    for k in kept:
        sequence.frame_path(tmp_path, k).write_bytes(picture(rng))
    assert sequence.prepare(tmp_path, marker_of(rng, seed=seed)[1]) == [k for k in range(FRAMES) if k not in kept]
    others = {
        "scene": marker_of(rng, seed=seed + 1)[1],
        "camera path": marker_of(rng, seed=seed, frames=FRAMES + 1)[1],
        "shading": marker_of(rng, seed=seed, shading="whitted")[1],
    }
    for what, other in others.items():
        with pytest.raises(RaybenchError, match=rf"holds {len(kept)} frames of another sequence \(its .*{what}"):
            sequence.prepare(tmp_path, other)
    with pytest.raises(RaybenchError, match=f"is {W}x{H}, this sequence's frames {W * 2}x{H}"):
        sequence.prepare(tmp_path, marker_of(rng, seed=seed, size=(W * 2, H))[1])
    assert json.loads((tmp_path / sequence.MARKER).read_text()) == mine  # none of them marked it
    for k in kept:
        sequence.frame_path(tmp_path, k).unlink()
    assert sequence.prepare(tmp_path, others["scene"]) == list(range(FRAMES))  # nothing left to mix with
    assert json.loads((tmp_path / sequence.MARKER).read_text()) == others["scene"]


def test_frames_without_a_marker_are_kept_where_their_size_is_right(tmp_path, rng):
    """An older raybench's folder: frames of the right size are taken (their
    scene cannot be known) and the folder is marked from then on."""
    _, mine = marker_of(rng)
    sequence.frame_path(tmp_path, 1).write_bytes(picture(rng))
    assert sequence.prepare(tmp_path, mine) == [0, 2, 3]
    assert json.loads((tmp_path / sequence.MARKER).read_text()) == mine


def test_a_damaged_marker_is_one_line_where_frames_are_there(tmp_path, rng):
    (tmp_path / sequence.MARKER).write_text("{not json")
    sequence.frame_path(tmp_path, 2).write_bytes(picture(rng))
    with pytest.raises(RaybenchError, match="is damaged \\(not valid JSON.*its 1 frames cannot be told"):
        sequence.prepare(tmp_path, marker_of(rng)[1])


def test_the_api_checks_the_folder_before_any_work(tmp_path, rng):
    """render_sequence refuses a folder of another sequence before it asks
    the cluster anything (its client is not even used here)."""
    scene, _ = marker_of(rng)
    sequence.frame_path(tmp_path, 0).write_bytes(picture(rng, W, H + 1))
    with pytest.raises(RaybenchError, match="frame_00000.png is 24x17"):
        raybench.cluster.render_sequence(None, scene, camera_path.orbit(Camera(), FRAMES), tmp_path, W, H, "cpu")


def frames_of(tmp_path, rng, count=3, size=(W, H)) -> list[Path]:
    paths = [sequence.frame_path(tmp_path, n) for n in range(count)]
    for path in paths:
        path.write_bytes(picture(rng, *size))
    return paths


def test_a_gif_of_its_own_frames_passes_pillows_bomb_guard(tmp_path, rng, monkeypatch):
    """Pillow's limit lowered below the frames' pixels (as 16384x16384 frames
    meet the real one): raybench's own frames, of the size it checked, make
    the GIF without Pillow's error or warning, the frames' pixels kept; any
    other file still meets the guard; the limit is Pillow's again after."""
    monkeypatch.setattr(Image, "MAX_IMAGE_PIXELS", W * H // 3)  # past twice the limit: Pillow's error
    paths = frames_of(tmp_path, rng)
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # DecompressionBombWarning included
        write_gif(paths, tmp_path / "own.gif", size=(W, H))
    with pytest.raises(Image.DecompressionBombError):  # the guard is Pillow's again
        Image.open(paths[0])
    assert Image.MAX_IMAGE_PIXELS == W * H // 3
    Image.MAX_IMAGE_PIXELS = None
    with Image.open(tmp_path / "own.gif") as gif:
        assert gif.n_frames == 3 and gif.size == (W, H)
    Image.MAX_IMAGE_PIXELS = W * H // 3
    with pytest.raises(RaybenchError, match="cannot read frame .*frame_00000.png.*decompression bomb"):
        write_gif(paths, tmp_path / "theirs.gif")  # no size: not known to be raybench's
    assert not (tmp_path / "theirs.gif").exists()


def test_a_gif_refuses_a_damaged_frame_or_one_of_another_size(tmp_path, rng):
    paths = frames_of(tmp_path, rng)
    paths[1].write_bytes(paths[1].read_bytes()[:60])  # cut short
    with pytest.raises(RaybenchError, match="cannot read frame .*frame_00001.png"):
        write_gif(paths, tmp_path / "a.gif", size=(W, H))
    paths[1].write_bytes(picture(rng, W, H + 2))
    with pytest.raises(RaybenchError, match=f"frame_00001.png is {W}x{H + 2}, not {W}x{H}"):
        write_gif(paths, tmp_path / "a.gif", size=(W, H))
    assert not (tmp_path / "a.gif").exists()


def test_a_gif_that_cannot_be_made_is_refused_before_tracing(capsys, monkeypatch, no_cluster):
    """A side past a GIF's 65535, or more memory than there is: one line,
    before the folder is made."""
    args = ["render", "--spheres", "3", "--path", "orbit", "--frames", "2", "-o", "frames", "--gif", "out.gif"]
    assert run([*args, "--size", f"{MAX_SIDE + 1}x8"]) == 2
    assert f"a GIF is at most {MAX_SIDE} pixels a side" in capsys.readouterr().err
    monkeypatch.setattr(raybench.host, "host_available_bytes", lambda: 10_000)
    assert run([*args, "--size", "64x48"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "2 frames of 64x48 need about" in err and "available" in err
    assert not Path("frames").exists() and not no_cluster


# --- the fuzzer, on sequence folders --------------------------------------------------------

SLOTS = ["missing", "missing", "good", "good", "good", "another size", "garbage", "folder", "symlink", "fifo"]


def test_fuzz_sequence_folders(tmp_path):
    """Generated frame folders: each frame's place empty, a good frame, or
    something else; a marker absent, this sequence's, another's or broken.
    The property, against a model of the rule: prepare() returns exactly the
    missing frames where every frame there is a PNG of this size and no
    marker of another sequence covers them, and else refuses in one line
    naming the first fault; the frames are never touched."""
    from collections import Counter

    from hypothesis import given
    from hypothesis import strategies as st
    from test_fuzz import budget

    seen = Counter()
    rng = np.random.default_rng(29)
    good, other_size = picture(rng), picture(rng, W, H + 3)
    _, mine = marker_of(rng, seed=1)
    _, theirs = marker_of(rng, seed=2)
    case = iter(range(1 << 30))

    @budget(80)
    @given(slots=st.lists(st.sampled_from(SLOTS), min_size=FRAMES, max_size=FRAMES),
           mark=st.sampled_from(["none", "mine", "theirs", "broken"]))  # fmt: skip
    def one(slots, mark):
        seen["tried"] += 1
        folder = tmp_path / str(next(case))
        folder.mkdir()
        for n, slot in enumerate(slots):
            path = sequence.frame_path(folder, n)
            if slot == "good":
                path.write_bytes(good)
            elif slot == "another size":
                path.write_bytes(other_size)
            elif slot != "missing":
                PLANTS[slot](path, rng)
        if mark != "none":
            text = "{broken" if mark == "broken" else json.dumps(mine if mark == "mine" else theirs)
            (folder / sequence.MARKER).write_text(text)
        before = {k: v for k, v in contents(folder).items() if k != sequence.MARKER}
        bad = [n for n, slot in enumerate(slots) if slot not in ("missing", "good")]
        kept = sum(slot == "good" for slot in slots)
        try:
            todo = sequence.prepare(folder, mine)
        except RaybenchError as exc:
            assert "\n" not in str(exc), exc
            if bad:
                assert f"frame_{bad[0]:05d}.png" in str(exc), (slots, exc)
            elif mark == "broken":
                assert kept and f"its sequence marker {sequence.MARKER} is damaged" in str(exc), (slots, exc)
            else:
                assert mark == "theirs" and kept and "frames of another sequence" in str(exc), (slots, mark, exc)
            seen["refused"] += 1
        else:
            assert not bad and not (mark in ("theirs", "broken") and kept), (slots, mark)
            assert todo == [n for n, slot in enumerate(slots) if slot == "missing"]
            assert json.loads((folder / sequence.MARKER).read_text()) == mine
            seen["prepared"] += 1
        assert {k: v for k, v in contents(folder).items() if k != sequence.MARKER} == before

    one()
    print(f"sequence folders: {dict(seen)}")
    assert seen["prepared"] >= 0.1 * seen["tried"] and seen["refused"] >= 0.3 * seen["tried"], seen
