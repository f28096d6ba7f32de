"""The fast kernels: the same pixels as the simple ones, because their cull
test only ever skips spheres the exact test would reject."""

import numpy as np
import pytest
from scenes import KINDS

import raybench
from raybench import backends, kernels
from raybench.backends import cuda as cuda_backend

# The algorithm as plain Python on NumPy float32 scalars: the same source the
# backends compile, run without a compiler.
K = kernels.make(lambda f: f)
f32 = np.float32


def grazing_pairs(rng, n):
    """n unit rays from the origin and spheres whose surface passes within a
    few float32 epsilons of the ray: the cases where the cull test could err.
    Radii from 1e-4 to 1e4, distances from 1e-2 to 1e5, in front and behind."""
    d = rng.normal(size=(n, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    side = rng.normal(size=(n, 3))
    side -= (side * d).sum(1, keepdims=True) * d
    side /= np.linalg.norm(side, axis=1, keepdims=True)
    r = 10.0 ** rng.uniform(-4, 4, n)
    along = 10.0 ** rng.uniform(-2, 5, n) * rng.choice([-1.0, 1.0], n, p=[0.2, 0.8])
    # distance of the centre from the ray line: r, nudged by up to ~1e-5 relative either way
    off = r * (1 + rng.uniform(-1e-5, 1e-5, n) * rng.choice([0, 1], n))
    centers = d * along[:, None] + side * off[:, None]
    return d.astype(np.float32), centers.astype(np.float32), r.astype(np.float32)


def test_cull_never_rejects_a_hit(rng):
    dirs, centers, radii = grazing_pairs(rng, 20000)
    exact_hits = culled = 0
    for (dx, dy, dz), (cx, cy, cz), r in zip(dirs, centers, radii):
        ex, ey, ez, q = _prepare(cx, cy, cz, r)
        t, d = K.prim.intersect_relative(ex, ey, ez, r, dx, dy, dz)
        if t > f32(0.0):  # the exact test found the sphere in front of the ray: a hit the kernels keep
            exact_hits += 1
            assert K.prim.may_hit(ex, ey, ez, q, dx, dy, dz), (dx, dy, dz, cx, cy, cz, r)
        elif not K.prim.may_hit(ex, ey, ez, q, dx, dy, dz):
            culled += 1
    # not vacuous: both sides of the boundary were exercised
    assert exact_hits > 2000 and culled > 200, (exact_hits, culled)


def _prepare(cx, cy, cz, r):
    relative = np.zeros((4, 1), np.float32)
    basis = np.zeros((4, 3), np.float32)
    spheres = np.array([[cx], [cy], [cz], [r], [0], [0], [0]], np.float32)
    K.prepare(0, basis, spheres, relative)
    return tuple(relative[:, 0])


def test_cull_skips_most_spheres_of_a_real_scene():
    """The point of the fast kernel: for the benchmark's scene most ray-sphere
    pairs are ruled out by the cull test alone."""
    scene = raybench.random_spheres(300, seed=1)
    basis = raybench.Camera().basis(40, 25)
    relative = np.zeros((4, 300), np.float32)
    for i in range(300):
        K.prepare(i, basis, scene.spheres, relative)
    kept = total = 0
    for y in range(0, 25, 3):
        for x in range(0, 40, 3):
            dx, dy, dz = K.primary_ray(x, y, 40, 25, basis)
            for i in range(300):
                total += 1
                kept += bool(K.prim.may_hit(*relative[:3, i], relative[3, i], dx, dy, dz))
    assert kept / total < 0.05, kept / total


@pytest.mark.parametrize("kind", sorted(KINDS))
@pytest.mark.parametrize("size", [(33, 7), (16, 20), (1, 5), (70, 31)])
def test_cpu_fast_equals_simple(rng, kind, size):
    """Bit for bit, including widths that are not a multiple of the SIMD group."""
    scene, camera = KINDS[kind](rng, int(rng.integers(1, 120)))
    width, height = size
    simple = raybench.render(scene, camera, width, height, device="cpu", kernel="simple")
    fast = raybench.render(scene, camera, width, height, device="cpu", kernel="fast", threads=3)
    assert np.array_equal(simple.hits, fast.hits) and np.array_equal(simple.image, fast.image)


@pytest.mark.parametrize("band", ["_pairs_band", "_wide_band"])
def test_both_cpu_fast_loops_equal_simple(rng, band):
    """The CPU picks one fast loop by its register width; both are checked
    here, whichever this machine would pick."""
    from raybench.backends.cpu import brute

    scene, camera = KINDS["overlapping"](rng, int(rng.integers(1, 120)))
    width, height = int(rng.integers(1, 50)), int(rng.integers(1, 20))
    simple = raybench.render(scene, camera, width, height, device="cpu", kernel="simple")
    tracer = raybench.backends.tracer("cpu", scene.spheres, width, height, kernel="fast", threads=2)
    tracer._kernel = getattr(brute, band)
    tracer.trace(camera.basis(width, height))
    assert np.array_equal(simple.hits, tracer.hits) and np.array_equal(simple.image, tracer.image)


def test_cpu_fast_sphere_prefix(rng):
    scene, camera = KINDS["generated"](rng, 50)
    tracer = backends.tracer("cpu", scene.spheres, 40, 24)
    tracer.trace(camera.basis(40, 24), 17)
    prefix = raybench.render(scene.head(17), camera, 40, 24, device="cpu", kernel="simple")
    assert np.array_equal(tracer.hits, prefix.hits) and np.array_equal(tracer.image, prefix.image)


@pytest.mark.slow
@pytest.mark.gpu
@pytest.mark.skipif(not cuda_backend.available(), reason="no CUDA GPU and the simulator is off")
# The simulator runs a Python thread per CUDA thread and polls them all while
# any waits at a barrier: 128 threads of the last shape took minutes there,
# so it gets 32 threads under the simulator and the real shape on a GPU.
@pytest.mark.parametrize(
    "rays,staged,trip,block",
    [
        (3, 8, 3, (4, 2)),
        (1, 45, 4, (5, 3)),
        (2, 1, 1, (8, 8)),
        (8, 256, 2, (8, 4) if cuda_backend.simulated() else (32, 4)),
        (8, 256, 4, (8, 4) if cuda_backend.simulated() else (16, 4)),
    ],
)
def test_cuda_fast_shapes_equal_cpu(rng, rays, staged, trip, block):
    """Every way of cutting the work (rays per thread, spheres staged in
    shared memory at a time and per trip of the cull loop, block shape, counts
    that are not a multiple of the staged batch or the trip) gives the CPU's picture: bit for bit
    under the simulator, within rounding on a GPU."""
    scene, camera = KINDS["overlapping"](rng, 40)
    width, height = (19, 23) if cuda_backend.simulated() else (301, 203)
    gpu = raybench.render(scene, camera, width, height, device="cuda", rays=rays, staged=staged, trip=trip, block=block)
    cpu = raybench.render(scene, camera, width, height, device="cpu", kernel="simple")
    if cuda_backend.simulated():
        assert np.array_equal(gpu.hits, cpu.hits) and np.array_equal(gpu.image, cpu.image)
    else:
        assert (gpu.hits != cpu.hits).mean() < 1e-3
        assert np.abs(gpu.image.astype(int) - cpu.image.astype(int)).max() <= 1 or (gpu.hits != cpu.hits).any()


@pytest.mark.parametrize(
    "device,options,match",
    [
        ("cpu", {"kernel": "quick"}, "kernel: must be one of"),
        ("cpu", {"kernel": "fast", "constant_count": True}, "simple kernel only"),
        ("cuda", {"rays": 0}, "rays: must be an integer from 1 to 16"),
        ("cuda", {"staged": 5000}, "staged: must be an integer from 1 to 3071"),
        ("cuda", {"block": (32, 32), "kernel": "fast"}, "fast kernel takes at most 256 threads"),
    ],
)
@pytest.mark.gpu
def test_bad_kernel_options(device, options, match):
    if device == "cuda" and not cuda_backend.available():
        pytest.skip("no CUDA GPU and the simulator is off")
    with pytest.raises(raybench.RaybenchError, match=match):
        raybench.render(raybench.random_spheres(3), width=8, height=8, device=device, **options)
