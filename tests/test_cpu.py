"""The CPU backend against the float64 reference, on fresh random scenes."""

import os
import subprocess
import sys

import numpy as np
import pytest
from reference import check_frame, trace
from scenes import KINDS

import raybench


@pytest.mark.parametrize("kernel", ["simple", "fast"])
@pytest.mark.parametrize("kind", sorted(KINDS))
@pytest.mark.parametrize("n,size", [(1, (40, 30)), (12, (57, 41)), (150, (96, 64)), (600, (80, 60))])
def test_cpu_matches_reference(rng, kind, n, size, kernel):
    scene, camera = KINDS[kind](rng, n)
    width, height = size
    frame = raybench.render(scene, camera, width, height, device="cpu", kernel=kernel)
    ref = trace(scene, camera, width, height)
    check_frame(frame, ref, context=f"{kind} n={n} {width}x{height}")


def test_scene_is_mostly_hit(rng):
    """Guard against a vacuous reference: the generated scenes show spheres."""
    scene, camera = KINDS["generated"](rng, 300)
    frame = raybench.render(scene, camera, 64, 48, device="cpu")
    assert (frame.hits >= 0).mean() > 0.5
    assert len(np.unique(frame.hits)) > 50


def test_empty_scene_is_background(rng):
    scene = raybench.random_spheres(0)
    frame = raybench.render(scene, width=33, height=17, device="cpu")
    assert (frame.hits == -1).all()
    ys, xs = np.mgrid[0:17, 0:33]
    expected = np.floor(np.clip(np.stack([xs / 1024, ys / 1024, xs / 786], -1), 0, 1) * 255 + 0.5)
    assert np.abs(frame.image.astype(int) - expected).max() <= 1


@pytest.mark.parametrize("options", [{"accel": "none", "kernel": "simple"}, {"accel": "bvh"}])
def test_background_bytes_are_exact_and_saturate(options):
    """The thesis's gradient (x / 1024, y / 1024, x / 786) to bytes, to the
    byte: red is exact in float32 (a division by a power of two, then 255x and
    a half, all under 2**24), so each of its bytes is known; past column 1024
    it saturates at 255, and blue past 786 (a clamp that let 1.2 through would
    wrap the byte round). Blue is held to the float64 value where that is not
    within rounding of a half. A frame 1100 wide, 3 high: a scale or a clamp
    off by one step changes some byte; test_empty_scene_is_background's
    tolerance of 1 cannot see that."""
    width, height = 1100, 3
    frame = raybench.render(raybench.random_spheres(0), width=width, height=height, device="cpu", **options)
    ys, xs = np.mgrid[0:height, 0:width]
    red = np.floor(np.minimum(xs / 1024, 1) * 255 + 0.5)
    green = np.floor(ys / 1024 * 255 + 0.5)
    blue = np.minimum(xs / 786, 1) * 255 + 0.5
    image = frame.image.astype(int)
    assert np.array_equal(image[..., 0], red), np.argwhere(image[..., 0] != red)[:5]
    assert np.array_equal(image[..., 1], green)
    clear = np.abs(blue - np.round(blue)) > 1e-3  # not at a rounding boundary
    assert np.array_equal(image[..., 2][clear], np.floor(blue)[clear])
    assert np.abs(image[..., 2] - np.floor(blue)).max() <= 1
    assert (image[:, 1024:, 0] == 255).all() and (image[:, 786:, 2] == 255).all()


def test_threads_do_not_change_the_picture(rng):
    scene, camera = KINDS["cloud"](rng, 80)
    one = raybench.render(scene, camera, 50, 40, device="cpu", threads=1)
    all_ = raybench.render(scene, camera, 50, 40, device="cpu")
    assert np.array_equal(one.image, all_.image) and np.array_equal(one.hits, all_.hits)


def test_constant_count_and_prefix(rng):
    from raybench import backends

    scene, camera = KINDS["generated"](rng, 40)
    runtime = raybench.render(scene, camera, 48, 32, device="cpu")
    constant = raybench.render(scene, camera, 48, 32, device="cpu", kernel="simple", constant_count=True)
    assert np.array_equal(runtime.image, constant.image) and np.array_equal(runtime.hits, constant.hits)
    tracer = backends.tracer("cpu", scene.spheres, 48, 32, threads=3)
    tracer.trace(camera.basis(48, 32), 15)
    prefix = raybench.render(scene.head(15), camera, 48, 32, device="cpu")
    assert np.array_equal(tracer.hits, prefix.hits) and np.array_equal(tracer.image, prefix.image)
    with pytest.raises(raybench.RaybenchError, match="sphere count"):
        tracer.trace(camera.basis(48, 32), 41)


@pytest.mark.parametrize("height,threads", [(7, 3), (10, 10), (5, 64), (1050, 16)])
def test_bands_cover_every_row_once(height, threads):
    from raybench.backends.cpu import bands

    rows = [y for a, b in bands(height, threads) for y in range(a, b)]
    assert rows == list(range(height))
    sizes = [b - a for a, b in bands(height, threads)]
    assert max(sizes) - min(sizes) <= 1


@pytest.mark.skipif(not hasattr(os, "sched_setaffinity"), reason="CPU affinity is Linux's")
def test_threads_follow_the_cores_the_process_may_use():
    """Under taskset or a container's cpuset the machine has more cores than
    the process may use: the CPU backend's and the builder's default threads
    are the usable ones, not os.cpu_count()."""
    code = (
        "import os; os.sched_setaffinity(0, {min(os.sched_getaffinity(0))}); "
        "from raybench.backends import cpu; from raybench import host; "
        "print(cpu.default_threads(), host.usable_cores(), os.cpu_count())"
    )
    out = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, check=True, timeout=300
    ).stdout.split()
    assert out[:2] == ["1", "1"], out
