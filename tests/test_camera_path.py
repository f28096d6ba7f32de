"""Camera paths (raybench.camera_path): the orbit's geometry and keyframes
files read strictly, against numbers computed here."""

import json

import numpy as np
import pytest

from raybench import Camera, RaybenchError, camera_path
from raybench.cli import run


def random_camera(rng) -> Camera:
    return Camera(tuple(rng.uniform(-5, 5, 3)), tuple(rng.uniform(-5, 5, 3)), (0.0, 1.0, 0.0), rng.uniform(20, 100))


def test_an_orbit_circles_the_look_at_point_about_up(rng):
    camera = random_camera(rng)
    frames = int(rng.integers(2, 50))
    path = camera_path.orbit(camera, frames)
    assert len(path) == frames and path[0].position == pytest.approx(camera.position)
    centre, up = np.array(camera.look_at), np.array(camera.up)
    arm = np.array(camera.position) - centre
    for i, cam in enumerate(path):
        assert (cam.look_at, cam.up, cam.fov_deg) == (camera.look_at, camera.up, camera.fov_deg)
        turned = np.array(cam.position) - centre
        assert np.linalg.norm(turned) == pytest.approx(np.linalg.norm(arm))
        assert turned @ up == pytest.approx(arm @ up, abs=1e-9)  # same height along up
        # the angle turned, in the plane across up, measured here by atan2
        flat_a, flat_b = arm - (arm @ up) * up, turned - (turned @ up) * up
        angle = np.arctan2(np.cross(flat_a, flat_b) @ up, flat_a @ flat_b) % (2 * np.pi)
        expected = 2 * np.pi * i / frames
        assert min(abs(angle - expected), 2 * np.pi - abs(angle - expected)) < 1e-9


def write_path(tmp_path, keyframes, **top):
    doc = {"format": "raybench-path", "version": 1, "keyframes": keyframes, **top}
    path = tmp_path / "path.json"
    path.write_text(json.dumps(doc))
    return path


def test_keyframes_are_met_and_joined_linearly(rng, tmp_path):
    keys = [random_camera(rng) for _ in range(int(rng.integers(2, 5)))]
    frames = 3 * (len(keys) - 1) + 1  # every third frame on a keyframe
    path = camera_path.load(str(write_path(tmp_path, [k.to_dict() for k in keys])), frames)
    assert len(path) == frames
    for k, key in enumerate(keys):
        assert path[3 * k].position == pytest.approx(key.position)
        assert path[3 * k].fov_deg == pytest.approx(key.fov_deg)
    a, b = np.array(keys[0].look_at), np.array(keys[1].look_at)
    assert path[1].look_at == pytest.approx(tuple(a + (b - a) / 3))


def test_one_keyframe_holds_the_camera(tmp_path):
    path = camera_path.load(str(write_path(tmp_path, [{"position": [1, 2, 3]}])), 4)
    assert [c.position for c in path] == [(1.0, 2.0, 3.0)] * 4 and path[0].look_at == Camera().look_at


@pytest.mark.parametrize(
    "keyframes, top, message",
    [
        ([], {}, "keyframes: must be a list of one or more"),
        ([{"position": [0, 0, 0], "zoom": 2}], {}, r"keyframes\[0\]\.zoom: unknown key"),
        ([{"position": [0, 0, "x"]}], {}, r"keyframes\[0\]: camera.position"),
        ([{}], {"speed": 1}, "speed: unknown key"),
        ([{"position": [0, 0, 2], "look_at": [0, 0, 0]}, {"position": [0, 0, -2], "look_at": [0, 0, 0]}], {},
         "frame 1 .*look_at: must differ"),
    ],
)  # fmt: skip
def test_bad_keyframes_are_refused_with_where(tmp_path, keyframes, top, message):
    with pytest.raises(RaybenchError, match=message):
        camera_path.load(str(write_path(tmp_path, keyframes, **top)), 3)


@pytest.mark.parametrize("frames", [0, -1, 100_000, 2.5, True])
def test_frames_must_be_a_count(frames):
    with pytest.raises(RaybenchError, match="frames: must be a whole number"):
        camera_path.orbit(Camera(), frames)


def test_cli_a_bad_path_file_is_one_line(tmp_path, capsys, monkeypatch):
    monkeypatch.delenv("RAYBENCH_SCHEDULER", raising=False)
    bad = write_path(tmp_path, [{"position": [0, 0, 0], "zoom": 2}])
    assert run(["render", "--spheres", "3", "--path", str(bad), "-o", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err
    assert "keyframes[0].zoom: unknown key" in err and err.count("\n") == 1
    assert not (tmp_path / "out").exists()
