"""The CUDA kernel: under numba's simulator where there is no GPU (CI), for real
on a machine with one. Same scenes, same reference as the CPU tests."""

import numpy as np
import pytest
from reference import check_frame, trace
from scenes import KINDS

import raybench
from raybench.backends import cuda as cuda_backend

SIM = cuda_backend.simulated()
pytestmark = [
    pytest.mark.gpu,
    pytest.mark.skipif(not cuda_backend.available(), reason="no CUDA GPU and the simulator is off"),
]

# The simulator runs every GPU thread as Python: keep its images small.
SIZES = [(24, 16), (19, 13)] if SIM else [(320, 200), (257, 129)]
COUNTS = [1, 25] if SIM else [1, 100, 1000]


@pytest.mark.slow
@pytest.mark.parametrize("kernel", ["simple", "fast"])
@pytest.mark.parametrize("kind", sorted(KINDS))
@pytest.mark.parametrize("n", COUNTS)
def test_cuda_matches_reference_and_cpu(rng, kind, n, kernel):
    scene, camera = KINDS[kind](rng, n)
    for (width, height), block in zip(SIZES, [(8, 8), (5, 3)]):
        context = f"{kernel} kernel, {kind} n={n} {width}x{height} block {block}"
        gpu = raybench.render(scene, camera, width, height, device="cuda", block=block, kernel=kernel)
        assert gpu.device == "cuda"
        ref = trace(scene, camera, width, height)
        check_frame(gpu, ref, context=context)
        cpu = raybench.render(scene, camera, width, height, device="cpu", kernel=kernel)
        if SIM:
            # Both run IEEE float32 without contraction: bit for bit the same.
            assert np.array_equal(gpu.hits, cpu.hits), context
            assert np.array_equal(gpu.image, cpu.image), context
        else:
            # The GPU compiler fuses multiply-adds; the pictures may differ only
            # where rounding decides, by at most one step.
            same = gpu.hits == cpu.hits
            assert (same | ref.ambiguous).all(), context
            # where a float32 tie gave another sphere, its colour is another sphere's
            step = np.abs(gpu.image.astype(int) - cpu.image.astype(int)).max(axis=2)
            assert step[same].max(initial=0) <= 1, context


@pytest.mark.parametrize("kernel", ["simple", "fast"])
def test_every_pixel_is_written(rng, kernel):
    """Blocks that overhang the image must neither skip nor spill pixels."""
    scene, camera = KINDS["generated"](rng, 10)
    width, height = SIZES[1]
    largest = (32, 32) if kernel == "simple" else (16, 16)  # the fast kernel's limit: 256 threads
    for block in [(1, 1), (7, 5), (32, 4)] if SIM else [(1, 1), (7, 5), largest, (16, 8)]:
        frame = raybench.render(scene, camera, width, height, device="cuda", block=block, kernel=kernel)
        ref = trace(scene, camera, width, height)
        check_frame(frame, ref, context=f"block {block}")


@pytest.mark.parametrize("block", [(0, 4), (64, 64), "ab"])
def test_bad_block_is_refused(block):
    with pytest.raises(raybench.RaybenchError, match="block"):
        raybench.render(raybench.random_spheres(3), width=8, height=8, device="cuda", block=block)


def test_constant_count_kernel_draws_the_same(rng):
    scene, camera = KINDS["generated"](rng, 12)
    width, height = SIZES[0]
    runtime = raybench.render(scene, camera, width, height, device="cuda")
    constant = raybench.render(scene, camera, width, height, device="cuda", kernel="simple", constant_count=True)
    assert np.array_equal(runtime.image, constant.image) and np.array_equal(runtime.hits, constant.hits)


def test_timed_frames_and_sphere_prefix(rng):
    """What the benchmark uses: kernel time from CUDA events (None under the
    simulator) and frames of the first k spheres."""
    from raybench import backends

    scene, camera = KINDS["generated"](rng, 30)
    width, height = SIZES[0]
    tracer = backends.tracer("cuda", scene.spheres, width, height)
    assert tracer.compile() >= 0
    kernel_ms = tracer.timed_trace(camera.basis(width, height), 10)
    assert (kernel_ms is None) if SIM else kernel_ms > 0
    prefix = raybench.render(scene.head(10), camera, width, height, device="cpu")
    assert np.array_equal(tracer.hits, prefix.hits) if SIM else (tracer.hits == prefix.hits).mean() > 0.999
    with pytest.raises(raybench.RaybenchError, match="sphere count"):
        tracer.trace(camera.basis(width, height), 31)


# Each of cuda's kernels: (options, shading). The packet walk's block is its
# default 8x4; 5x3 puts a band's edge inside blocks of the others.
ROW_KERNELS = [
    ({"accel": "none", "kernel": "simple", "block": (5, 3)}, "thesis"),
    ({"accel": "none", "kernel": "fast", "block": (8, 2), "rays": 2}, "thesis"),
    ({"accel": "none", "kernel": "simple", "constant_count": True}, "thesis"),
    ({"accel": "bvh", "walk": "ray", "block": (5, 3)}, "thesis"),
    ({"accel": "bvh", "walk": "packet"}, "thesis"),
    ({"accel": "bvh", "block": (5, 3)}, "whitted"),
]


@pytest.mark.slow
@pytest.mark.parametrize("options, shading", ROW_KERNELS)
def test_rows_are_the_whole_frames_rows(rng, options, shading):
    """trace(rows=...) on every cuda kernel: a cluster's tile, each pixel as the whole frame has it.
    Between the two, a frame looking away (background only) fills the
    buffers, so a band left untraced cannot pass for traced."""
    scene = raybench.random_spheres(int(rng.integers(10, 25)), seed=int(rng.integers(2**31)), materials=True)
    camera = raybench.Camera(position=tuple(rng.uniform(-0.3, 0.3, 3)))
    away = raybench.Camera(position=camera.position, look_at=tuple(2 * np.array(camera.position) - camera.look_at))
    width, height = (16, 11) if SIM else SIZES[0]  # four frames of every kernel: small on the simulator
    with raybench.Renderer(scene, width, height, device="cuda", shading=shading, **options) as renderer:
        whole = renderer.render(camera)
        # a band through a row that sees a sphere, so the test is not of background alone
        seen = int(rng.choice(np.flatnonzero((whole.hits >= 0).any(axis=1))))
        first = int(rng.integers(0, seen + 1))
        end = int(rng.integers(seen + 1, height + 1))
        assert (whole.hits[first:end] >= 0).any() and (renderer.render(away).hits == -1).all()
        band = renderer.render(camera, rows=(first, end))
        np.testing.assert_array_equal(band.image, whole.image[first:end])
        np.testing.assert_array_equal(band.hits, whole.hits[first:end])
        if shading == "whitted":
            assert band.rays["primary"] == (end - first) * width
        assert renderer.render(camera).rays == whole.rays  # a whole frame after a band: all of it again
