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


@pytest.mark.parametrize("accel, shading", [("bvh", "thesis"), ("none", "thesis"), ("bvh", "whitted")])
def test_rows_are_the_whole_frames_rows(rng, accel, shading):
    """Renderer.render(rows=...): a cluster's tile, each pixel as the whole frame has it.
    Between the two, a frame looking away (background only) fills the
    renderer's buffers, so a band left untraced cannot pass for traced."""
    scene = raybench.random_spheres(int(rng.integers(10, 60)), seed=int(rng.integers(2**31)), materials=True)
    camera = raybench.Camera(position=tuple(rng.uniform(-0.3, 0.3, 3)))
    away = raybench.Camera(position=camera.position, look_at=tuple(2 * np.array(camera.position) - camera.look_at))
    with raybench.Renderer(scene, 64, 48, device="cpu", threads=2, accel=accel, shading=shading) as renderer:
        whole = renderer.render(camera)
        # a band through a row that sees a sphere, so the test is not of background alone
        seen = int(rng.choice(np.flatnonzero((whole.hits >= 0).any(axis=1))))
        first = 8 * int(rng.integers(0, seen // 8 + 1))
        end = int(rng.integers(seen + 1, 49))
        assert (whole.hits[first:end] >= 0).any() and (renderer.render(away).hits == -1).all()
        band = renderer.render(camera, rows=(first, end))
        np.testing.assert_array_equal(band.image, whole.image[first:end])
        np.testing.assert_array_equal(band.hits, whole.hits[first:end])
        if shading == "whitted":  # the band's rays alone: one primary ray a pixel of it
            assert band.rays["primary"] == (end - first) * 64
            assert renderer.render(camera, rows=(0, 48)).rays == whole.rays
        for bad in [(3, 10), (8, 8), (0, 49), (-8, 8), "rows"]:
            with pytest.raises(raybench.RaybenchError, match="rows"):
                renderer.render(camera, rows=bad)
