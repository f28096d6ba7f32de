"""backends/options.py: each device's options checked in one place, before
any device is opened: what is wrong is one line naming the option, and what
is right comes back with the defaults filled in, as the Tracer then uses it."""

import math

import numpy as np
import pytest

import raybench
from raybench import backends
from raybench.backends import options
from raybench.errors import RaybenchError
from raybench.host import usable_cores
from raybench.kernels.primitives import KINDS
from raybench.lighting import Shading

# Every integer option, with its bounds and what else it needs to apply.
INTEGERS = [
    ("cpu", "threads", 1, options.MAX_THREADS, {}),
    ("cuda", "rays", 1, options.MAX_RAYS_PER_THREAD, {"kernel": "fast"}),
    ("cuda", "staged", 1, options.MAX_STAGED, {"kernel": "fast"}),
    ("cuda", "trip", 1, options.MAX_TRIP, {"kernel": "fast"}),
    ("cuda", "treelet_passes", 1, options.MAX_TREELET_PASSES, {"build": "gpu", "quality": "treelet"}),
]


def shading(rng) -> Shading:
    scene = raybench.random_spheres(int(rng.integers(1, 20)), int(rng.integers(1000)), materials=True)
    return Shading.of(scene, int(rng.integers(1, 6)), int(rng.integers(1, 5)))


@pytest.mark.parametrize("device,name,low,high,needs", INTEGERS)
def test_an_integer_option_takes_its_range_and_refuses_the_rest(rng, device, name, low, high, needs):
    inside = int(rng.integers(low, high + 1))
    assert getattr(options.checked(device, {**needs, name: inside}), name) == inside
    assert getattr(options.checked(device, {**needs, name: np.int16(low)}), name) == low
    for bad in (low - 1 - int(rng.integers(100)), high + 1 + int(rng.integers(100)), True, float(inside), str(inside)):
        with pytest.raises(RaybenchError, match=f"^{name}: must be an integer from {low} to {high}, got "):
            options.checked(device, {**needs, name: bad})


@pytest.mark.parametrize("device", backends.DEVICES)
def test_an_option_of_another_device_is_named_with_the_devices_own(device):
    other = next(n for d in backends.DEVICES for n in options.NAMES[d] if n not in options.NAMES[device])
    with pytest.raises(RaybenchError) as caught:
        options.checked(device, {other: 1})
    message = str(caught.value)
    assert message.startswith(f"option {other!r} does not apply to device {device} (its options: ")
    assert all(name in message for name in options.NAMES[device]) and "\n" not in message


def test_the_defaults_are_filled_in():
    cpu = options.checked("cpu", {})
    # the tree's width is left to the tracer, which takes its kind of primitive's
    assert (cpu.accel, cpu.kernel, cpu.threads, cpu.tree_width) == ("bvh", None, usable_cores(), None)
    assert options.KIND_TREE_WIDTH == {
        "sphere": {"thesis": 4, "whitted": 4},
        "triangle": {"thesis": 4, "whitted": 4},
        "mixed": {"thesis": 4, "whitted": 4},
    }
    assert set(options.KIND_TREE_WIDTH) == set(KINDS)  # every kind has its default
    assert options.checked("cpu", {"accel": "none"}).kernel == "fast"
    cuda = options.checked("cuda", {"kernel": "fast"})
    assert (cuda.accel, cuda.rays, cuda.staged, cuda.trip, cuda.block) == (
        "none", options.RAYS_PER_THREAD, options.STAGED, options.TRIP, None
    )  # fmt: skip
    assert options.checked("cuda", {"kernel": "simple"}).rays == 1  # one ray a thread but in the fast kernel
    gpu = options.checked("cuda", {"build": "gpu"})
    assert (gpu.build, gpu.quality, gpu.refit_limit) == ("gpu", "sah", 1.3)
    wgpu = options.checked("wgpu", {})
    assert (wgpu.walk, wgpu.workgroup, wgpu.build) == ("ray", options.DEFAULT_WORKGROUP["ray"], "host")
    assert options.checked("wgpu", {"walk": "packet"}).workgroup == options.DEFAULT_WORKGROUP["packet"]
    assert options.checked("wgpu", {"accel": "none"}).workgroup == options.DEFAULT_WORKGROUP["none"]


def test_whitted_shading_sets_the_schedule_and_refuses_what_it_cannot_use(rng):
    whitted = shading(rng)
    for device in ("cuda", "wgpu"):
        assert options.checked(device, {}).schedule is None
        assert options.checked(device, {}, whitted).schedule == "wavefront"
        assert options.checked(device, {"schedule": "pixel"}, whitted).schedule == "pixel"
        with pytest.raises(RaybenchError, match="^schedule 'pixel': applies to Whitted shading only$"):
            options.checked(device, {"schedule": "pixel"})
        with pytest.raises(RaybenchError, match="^walk 'packet': applies to the thesis's shading only"):
            options.checked(device, {"walk": "packet"}, whitted)
    with pytest.raises(RaybenchError, match="^wave_grid: applies to the wavefront schedule only"):
        options.checked("cuda", {"schedule": "pixel", "wave_grid": 64}, whitted)
    with pytest.raises(RaybenchError, match="^kernel 'fast': applies to the thesis's shading only"):
        options.checked("cpu", {"kernel": "fast"}, whitted)
    assert options.checked("cpu", {"accel": "none"}, whitted).kernel == "simple"


@pytest.mark.parametrize("device", ["cuda", "wgpu"])
def test_the_gpu_builds_variants_apply_to_the_gpu_build_only(rng, device):
    for name, value in (("quality", "lbvh"), ("refit_limit", 2.0)):
        with pytest.raises(RaybenchError, match=f"^{name}: applies to the tree built on the GPU only"):
            options.checked(device, {name: value})
    limit = float(rng.uniform(0, 10))
    assert options.checked(device, {"build": "gpu", "refit_limit": limit}).refit_limit == limit
    assert options.checked(device, {"build": "gpu", "refit_limit": math.inf}).refit_limit == math.inf
    for bad in (-limit - 0.1, math.nan, "2", True):
        with pytest.raises(RaybenchError, match="^refit_limit: must be a number of at least 0"):
            options.checked(device, {"build": "gpu", "refit_limit": bad})
    with pytest.raises(RaybenchError, match="^quality: must be one of sah, "):
        options.checked(device, {"build": "gpu", "quality": "best"})
    if device == "wgpu":  # the WGSL build has no treelets
        with pytest.raises(RaybenchError, match="^quality: must be one of sah, lbvh, got 'treelet'"):
            options.checked(device, {"build": "gpu", "quality": "treelet"})
    else:
        with pytest.raises(RaybenchError, match="^treelet_passes: applies to quality 'treelet' only"):
            options.checked(device, {"build": "gpu", "treelet_passes": 2})


@pytest.mark.parametrize(
    "device,given,message",
    [
        ("cpu", {"accel": "tree"}, "accel: must be one of bvh, none, got 'tree'"),
        ("cpu", {"accel": "bvh", "kernel": "simple"}, "kernel: applies to brute force only"),
        ("cpu", {"accel": "none", "tree_width": 4}, "tree_width: applies to the BVH's packets only"),
        ("cuda", {"accel": "bvh", "staged": 64}, "staged: applies to brute force only"),
        ("cuda", {"block": (0, 8)}, "block: must be two integers (x, y), each at least 1, got (0, 8)"),
        ("cuda", {"block": (16, 32)}, "block: the BVH walk takes at most 256 threads per block"),
        ("cuda", {"kernel": "simple", "block": (64, 32)}, "block: x*y must be at most 1024 threads, got 64x32"),
        ("cuda", {"accel": "none", "build": "gpu"}, "build: applies to the BVH only"),
        ("wgpu", {"kernel": "fast"}, "kernel: the wgpu backend has the simple kernel only"),
        ("wgpu", {"workgroup": 16}, "workgroup: must be two integers (x, y), got 16"),
        ("wgpu", {"adapter": 3}, "adapter: must be an adapter's name (text), got 3"),
    ],
)
def test_a_wrong_option_is_one_line_that_names_it(device, given, message):
    with pytest.raises(RaybenchError) as caught:
        options.checked(device, given)
    assert str(caught.value).startswith(message) and "\n" not in str(caught.value)


def test_the_tracer_uses_the_options_checked(rng):
    scene = raybench.random_spheres(int(rng.integers(1, 30)), int(rng.integers(1000)))
    threads = int(rng.integers(1, 3))
    with backends.tracer("cpu", scene.spheres, 8, 8, threads=threads, tree_width=2) as tracer:
        assert tracer.options == options.checked("cpu", {"threads": threads, "tree_width": 2})
        assert (tracer.threads, tracer.tree_width) == (threads, 2)
    with backends.tracer("cpu", scene.spheres, 8, 8, kernel="simple") as tracer:
        assert (tracer.accel, tracer.kernel, tracer.tree_width) == ("none", "simple", None)
