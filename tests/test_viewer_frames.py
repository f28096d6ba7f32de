"""benchmarks/viewer_frames.py: the viewer's frames a second, headless. Its record is the
results schema's, and what its loop drew is what the viewer shows: raybench.render's frame
of the same camera on the same device, byte for byte, as the window tests compare them."""

import importlib.util
import json
from pathlib import Path

import numpy as np
import pytest

import raybench
from raybench.backends import bands
from raybench.bench import results

BENCHMARKS = Path(__file__).resolve().parent.parent / "benchmarks"


@pytest.fixture
def viewer_frames(monkeypatch):
    monkeypatch.syspath_prepend(str(BENCHMARKS))  # its `import _harness`
    spec = importlib.util.spec_from_file_location("viewer_frames", BENCHMARKS / "viewer_frames.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


@pytest.mark.slow
@pytest.mark.gpu
@pytest.mark.parametrize("device, banded", [("cpu", False), ("wgpu", False), ("wgpu", True)])
def test_the_loop_draws_what_the_viewer_shows_and_records_it(
    viewer_frames, adapter, device, banded, tmp_path, capsys, monkeypatch
):
    """The quad draws through wgpu (lavapipe here); the frames are traced on the cpu through
    the viewer's worker thread, or on wgpu into the quad's own texture (two draws a frame).
    banded: the wavefront's queues capped at 64 KiB (backends/bands.py), so that the
    viewer's wgpu frames are traced into its texture in bands of a few rows; they are
    still raybench.render's frame in one piece, and its ray counts."""
    plans = []
    if banded:
        monkeypatch.setattr(bands, "QUEUE_BYTES", 64 * 2**10)
        plan = bands.plan
        monkeypatch.setattr(bands, "plan", lambda *args: plans.append(plan(*args)) or plans[-1])
    out = tmp_path / "viewer.jsonl"
    argv = ["--device", device, "--spheres", "200", "--size", "40x24", "--frames", "3", "--warmup", "1"]
    seen = []
    assert viewer_frames.main([*argv, "--adapter", adapter, "--out", str(out), "--label", "probe"], seen) == 0
    (record,) = results.read(out)
    assert [json.loads(line) for line in capsys.readouterr().out.splitlines()] == [record]
    assert (record["suite"], record["quantity"], record["device"]) == ("parts", "viewer-frame", device)
    assert (record["spheres"], record["width"], record["height"], record["samples"]) == (200, 40, 24, 3)
    assert record["run"]["label"] == "probe" and record["run"]["settings"]["target_format"] == "bgra8unorm"
    values = record["values"]
    assert values["frames_per_s"] == pytest.approx(3 / values["wall_s"])
    assert sum(record["samples_ms"]) == pytest.approx(values["wall_s"] * 1e3, rel=1e-3)
    draws = 2 if device == "wgpu" else 1
    assert values["draws_per_frame"] == draws and values["window_cap_fps"] == viewer_frames.MAX_FPS / draws
    (measured,) = seen
    last = measured.last
    request = last.request
    shading = request.shading
    named = {"adapter": adapter} if device == "wgpu" else {}
    assert record["options"] == {
        "shading": "whitted",
        "depth": shading.depth,
        "shadow_samples": shading.shadow_samples,
        **named,
    }
    assert request.number == 4 and request.count == 200 and (request.width, request.height) == (40, 24)
    # the camera orbits: the last frame's is a quarter turn short of a full one, not the viewer's home
    assert not np.allclose(request.camera.position, raybench.Camera().position)
    assert not banded or 1 <= plans[-1].rows <= 24 // 3  # the frames drawn were banded
    monkeypatch.setattr(bands, "QUEUE_BYTES", None)
    expected = raybench.render(
        request.scene.head(request.count),
        request.camera,
        40,
        24,
        device=device,
        shading="whitted",
        depth=shading.depth,
        shadow_samples=shading.shadow_samples,
        **named,
    )
    assert measured.drawn.shape == (24, 40, 3) and np.array_equal(measured.drawn, expected.image)
    assert last.frame.rays == expected.rays and values["rays_per_frame"] >= 40 * 24  # a primary ray a pixel at least
    assert len(np.unique(measured.drawn.reshape(-1, 3), axis=0)) > 20  # a picture, not a cleared target


def test_bad_options_are_refused_before_any_work(viewer_frames, capsys):
    for argv, said in (
        (["--warmup", "0"], "--warmup: at least 1"),
        (["--spheres", "0"], "--spheres: at least 1"),
        (["--size", "40by24"], "--size: must be WIDTHxHEIGHT"),
        (["--depth", "-1"], "depth"),
    ):
        with pytest.raises(SystemExit) as exited:
            viewer_frames.main(argv)
        assert exited.value.code == 2
        assert said in capsys.readouterr().err, argv
