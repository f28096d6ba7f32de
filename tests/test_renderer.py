"""Renderer: a scene kept ready across frames gives render()'s frames."""

import numpy as np
import pytest

import raybench


@pytest.mark.parametrize(
    "device, shading", [("cpu", "thesis"), ("cpu", "whitted"), pytest.param("cuda", "thesis", marks=pytest.mark.gpu)]
)
def test_frames_are_render_frames(rng, device, shading):
    scene = raybench.random_spheres(int(rng.integers(5, 60)), seed=int(rng.integers(2**31)), materials=True)
    # from anywhere near the default camera, towards the spheres: three different pictures
    cameras = [raybench.Camera(position=tuple(rng.uniform(-1, 1, 3)), look_at=(0, 0, 15)) for _ in range(3)]
    with raybench.Renderer(scene, 24, 16, device=device, shading=shading) as renderer:
        frames = [renderer.render(camera) for camera in cameras]
        assert renderer.render(cameras[0], hits=False).hits is None
    for camera, got in zip(cameras, frames):
        want = raybench.render(scene, camera, 24, 16, device=device, shading=shading)
        assert np.array_equal(got.image, want.image) and np.array_equal(got.hits, want.hits)
        assert got.rays == want.rays and (got.rays is None) == (shading == "thesis")
    # each frame owns its arrays: the next one did not overwrite them
    assert not all(np.array_equal(frames[0].image, f.image) for f in frames[1:])


def test_a_closed_renderer_says_so():
    renderer = raybench.Renderer(raybench.random_spheres(3), 8, 8, device="cpu")
    renderer.close()
    with pytest.raises(raybench.RaybenchError, match="renderer: it is closed"):
        renderer.render()


@pytest.mark.parametrize(
    "kwargs, message",
    [
        ({"scene": "x"}, "scene: must be a raybench.Scene"),
        ({"width": 0}, "size"),
        ({"depth": 3}, "apply to shading='whitted' only"),
        ({"shading": "flat"}, "shading: must be one of"),
    ],
)
def test_bad_arguments_are_refused(kwargs, message):
    args = {"scene": raybench.random_spheres(3), "width": 8, "height": 8, "device": "cpu", **kwargs}
    with pytest.raises(raybench.RaybenchError, match=message):
        raybench.Renderer(**args)
