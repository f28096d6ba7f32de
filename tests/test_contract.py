"""Every backend's Tracer keeps the written contract (backends.contract.Tracer)."""

import numpy as np
import pytest

import raybench
from raybench import backends
from raybench.backends.contract import Tracer


# cuda: the real GPU, or numba's simulator under NUMBA_ENABLE_CUDASIM=1 (conftest)
@pytest.mark.parametrize(
    "device", ["cpu", pytest.param("cuda", marks=pytest.mark.gpu), pytest.param("wgpu", marks=pytest.mark.gpu)]
)
@pytest.mark.parametrize("accel", ["bvh", "none"])
def test_tracer_keeps_the_contract(device, accel, request):
    spheres = raybench.random_spheres(20, seed=3).spheres
    options = {"adapter": request.getfixturevalue("adapter")} if device == "wgpu" else {}
    with backends.tracer(device, spheres, 16, 8, accel=accel, **options) as tracer:
        assert isinstance(tracer, Tracer)
        assert (tracer.name, tracer.width, tracer.height, tracer.count, tracer.accel) == (device, 16, 8, 20, accel)
        assert (tracer.build_s is None) == (accel == "none")
        assert isinstance(tracer.compile(), float)
        image, hits = tracer.trace(raybench.Camera().basis(16, 8))
        assert image.shape == (8, 16, 3) and image.dtype == np.uint8
        assert hits.shape == (8, 16) and hits.dtype == np.int32
        ms = tracer.timed_trace(raybench.Camera().basis(16, 8))
        assert ms is None or ms >= 0
        # arrays handed to it between frames are those the next frame is traced into, and returned
        own = image.copy(), hits.copy()
        tracer.image, tracer.hits = tracer.host_array(image.shape, np.uint8), tracer.host_array(hits.shape, np.int32)
        handed = tracer.image, tracer.hits
        got = tracer.trace(raybench.Camera().basis(16, 8))
        assert got[0] is handed[0] and got[1] is handed[1]
        np.testing.assert_array_equal(got[0], own[0])
        np.testing.assert_array_equal(got[1], own[1])
