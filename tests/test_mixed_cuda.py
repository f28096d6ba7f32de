"""Spheres and triangles in one scene on cuda (the mixed kind, one tree of
typed leaves): under numba's simulator where there is no GPU (tiny frames:
every simulated thread is a Python thread), for real on the GPU machine.
The thesis's frame hits test_mixed's float64 brute force over both kinds,
on the host's tree and the GPU builder's, by the ray walk, the packet walk
and brute force; Whitted's wavefront is its pixel program's frame."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest
from test_mixed import both_reference, scenes
from test_triangle_cuda import SIM, frames_alike

from raybench import Light, Material, Scene, backends, render
from raybench.backends import cuda as cuda_backend
from raybench.lighting import Shading
from raybench.scene_meshes import mixed_leaves

pytestmark = [
    pytest.mark.gpu,
    pytest.mark.skipif(not cuda_backend.available(), reason="no CUDA GPU and the simulator is off"),
]

W, H = (24, 16) if SIM else (160, 120)
PACKET_SIZE = (16, 8) if SIM else (W, H)


def test_thesis_frames_hit_the_float64_reference_on_both_trees():
    """The host's SAH tree and the GPU builder's: the float64 reference's
    primitive on every pixel clear of an outline or a tie, one frame."""
    both = scenes()[0]
    index, _t, clear, _o, _d = both_reference(both, W, H)
    host = render(both, None, W, H, device="cuda", walk="ray")
    assert host.device == "cuda"
    assert (host.hits.ravel()[clear] == index[clear]).mean() >= (1.0 if SIM else 0.995)
    leaves = mixed_leaves(both.spheres, both.triangles)
    with backends.tracer("cuda", leaves, W, H, primitive="mixed", build="gpu", walk="ray") as tracer:
        image, hits = tracer.trace(both.camera.basis(W, H))
        assert tracer.bvh.built_on == "gpu"
        frames_alike(SimpleNamespace(image=image, hits=hits), host)


@pytest.mark.parametrize("options", [{"walk": "packet"}, {"accel": "none", "kernel": "simple"}])
def test_packet_walk_and_brute_force_give_the_ray_walks_frame(options):
    """A block's rays walking as one packet, and brute force: the ray walk's frame."""
    both = scenes()[0]
    width, height = PACKET_SIZE
    ray = render(both, None, width, height, device="cuda", walk="ray")
    frames_alike(render(both, None, width, height, device="cuda", **options), ray)


@pytest.mark.slow
def test_whitted_wavefront_is_the_pixel_program():
    """A mirror sphere and a glass one over a triangle floor, one light: the
    wavefront's frame (its walks read the typed leaves from its packed copy)
    is the pixel program's, within a step where sums round the other way."""
    light = Light(position=(0.0, 8.0, 2.0), color=(1.0, 1.0, 1.0), intensity=1.0)
    base = scenes()[0]
    mirror, glass = Material(reflect=0.8), Material(transmit=0.9, ior=1.5)
    scene = Scene(base.centers, base.radii, base.colors, base.camera, materials=[mirror, glass, Material()],
                  meshes=base.meshes, lights=[light])  # fmt: skip
    shading = Shading.of(scene, 2, 1)
    leaves = scene.traced().leaves

    def frame(**options):
        with backends.tracer("cuda", leaves, W, H, shading, primitive="mixed", **options) as tracer:
            image, hits = tracer.trace(scene.camera.basis(W, H))
            return image.copy(), hits.copy(), tracer.ray_counts.copy()

    wave, pixel = frame(build="gpu"), frame(schedule="pixel")
    assert wave[2][1] > 0 and wave[2][2] > 0 and wave[2][3] > 0  # shadow, reflection and refraction rays
    steps = np.abs(wave[0].astype(int) - pixel[0].astype(int)).max(axis=2)
    if SIM:
        assert np.array_equal(wave[1], pixel[1]) and np.array_equal(wave[2], pixel[2])
    assert (steps > 1).mean() <= 0.01
