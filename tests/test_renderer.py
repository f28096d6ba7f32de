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
    for call in (renderer.render, renderer.compile, lambda: renderer.update(raybench.random_spheres(3).spheres)):
        with pytest.raises(raybench.RaybenchError, match="renderer: it is closed"):
            call()


@pytest.mark.parametrize("accel", ["bvh", "none"])
def test_count_and_update_give_the_frames_of_those_spheres(rng, accel):
    """render(count=k) is the frame of the scene's first k spheres, and after
    update(moved) the frame of the moved spheres: each against a one-shot
    render() of a scene made of exactly those spheres."""
    n = int(rng.integers(20, 80))
    scene = raybench.random_spheres(n, seed=int(rng.integers(2**31)))
    camera = raybench.Camera(position=tuple(rng.uniform(-0.5, 0.5, 3)))
    k = int(rng.integers(1, n))
    moved = scene.spheres.copy()
    moved[:3] += rng.uniform(-1.5, 1.5, (3, n)).astype(np.float32)
    with raybench.Renderer(scene, 40, 30, device="cpu", accel=accel) as renderer:
        assert renderer.compile() >= 0
        first_k = renderer.render(camera, count=k)
        assert renderer.update(moved) == ("build" if accel == "bvh" else None)
        after = renderer.render(camera)
        with pytest.raises(raybench.RaybenchError, match="sphere count"):
            renderer.render(camera, count=n + 1)
    moved_scene = raybench.Scene(moved[:3].T, moved[3], moved[4:7].T)
    for got, alone in ((first_k, scene.head(k)), (after, moved_scene)):
        want = raybench.render(alone, camera, 40, 30, device="cpu", accel=accel)
        assert np.array_equal(got.image, want.image) and np.array_equal(got.hits, want.hits)
    assert not np.array_equal(first_k.hits, after.hits)


def test_a_shading_made_ahead_is_whitted_shading(rng):
    scene = raybench.random_spheres(int(rng.integers(5, 40)), seed=int(rng.integers(2**31)), materials=True)
    depth, samples = int(rng.integers(1, 6)), int(rng.integers(1, 5))
    shading = raybench.lighting.Shading.of(scene, depth, samples)
    with raybench.Renderer(scene, 24, 16, device="cpu", shading=shading) as renderer:
        got = renderer.render()
    want = raybench.render(scene, None, 24, 16, device="cpu", shading="whitted", depth=depth, shadow_samples=samples)
    assert np.array_equal(got.image, want.image) and got.rays == want.rays
    with pytest.raises(raybench.RaybenchError, match="a Shading holds its own"):
        raybench.Renderer(scene, 8, 8, device="cpu", shading=shading, depth=2)


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
