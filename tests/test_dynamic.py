"""Spheres that move every frame: each device's Tracer.update, then frames of
the moved spheres, which must be the brute force's pictures of them."""

import numpy as np
import pytest
from scenes import SCENES
from test_bvh import brute

import raybench
from raybench import animate
from raybench.backends import cuda as cuda_backend

SIZE = (19, 13)


def moving_frames(rng, device, **options):
    """Two moved frames of a small scene on device: update's answers."""
    scene, camera = SCENES["generated"](rng, int(rng.integers(10, 30)))
    orbits = animate.Orbits(scene.spheres, int(rng.integers(2**31)))
    kinds = []
    with raybench.backends.tracer(device, scene.spheres, *SIZE, **options) as tracer:
        for t in sorted(rng.uniform(0, 10, 2)):
            spheres = orbits.at(float(t))
            kinds.append(tracer.update(spheres))
            tracer.trace(camera.basis(*SIZE))
            want = brute(raybench.Scene(spheres[:3].T, spheres[3], spheres[4:].T), camera, *SIZE)
            assert np.array_equal(tracer.hits, want.hits) and np.array_equal(tracer.image, want.image)
    return kinds


@pytest.mark.parametrize("accel", ["bvh", "none"])
def test_cpu_frames_follow_the_spheres(rng, accel):
    assert moving_frames(rng, "cpu", accel=accel) == (["build"] * 2 if accel == "bvh" else [None] * 2)


@pytest.mark.gpu
@pytest.mark.parametrize("build", ["host", "gpu"])
def test_cuda_frames_follow_the_spheres(rng, build):
    if not cuda_backend.available():
        pytest.skip("no CUDA GPU and the simulator is off")
    kinds = moving_frames(rng, "cuda", build=build)
    assert set(kinds) <= ({"refit", "build"} if build == "gpu" else {"build"})


@pytest.mark.gpu
def test_wgpu_frames_follow_the_spheres(rng, adapter):
    assert moving_frames(rng, "wgpu", adapter=adapter) == ["build"] * 2


def test_update_refuses_other_spheres_in_one_line():
    spheres = raybench.random_spheres(5).spheres
    with raybench.backends.tracer("cpu", spheres, 4, 4) as tracer:
        with pytest.raises(raybench.RaybenchError, match=r"update: spheres must be a \(7, 5\) float32 array"):
            tracer.update(spheres.astype(np.float64))
