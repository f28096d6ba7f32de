"""backends.cuda.launch: a launch repeated with its arguments converted once
does what numba-cuda's own launch does. Under numba's simulator it launches
through numba-cuda every time; on a GPU the test also requires the fast path."""

import numpy as np
import pytest
from numba import cuda

from raybench.backends import cuda as cuda_backend
from raybench.backends.cuda.launch import Prepared

pytestmark = [
    pytest.mark.gpu,
    pytest.mark.skipif(not cuda_backend.available(), reason="no CUDA GPU and the simulator is off"),
]


@cuda.jit
def axpy(a, x, y, n, out):
    i = cuda.grid(1)
    if i < n:
        out[i] = a * x[i] + y[i]
        y[i] = out[i]


@cuda.jit
def bump(x):
    i = cuda.grid(1)
    if i < x.size:
        x[i] += 1


def test_a_prepared_launch_repeats_the_kernel_on_the_same_arrays(rng):
    n = int(rng.integers(1, 3000))
    x, y = rng.random(n, np.float32), rng.random(n, np.float32)
    a = np.float32(rng.random())
    dx, dy, dout = cuda.to_device(x), cuda.to_device(y), cuda.device_array(n, np.float32)
    blocks = (n + 127) // 128
    step = Prepared(axpy, blocks, 128, a, dx, dy, n, dout)  # launched once here
    want = y.copy()
    want = a * x + want
    for _ in range(int(rng.integers(2, 5))):
        step()
        want = a * x + want  # float32 throughout, one rounding a multiply and one an add
    cuda.synchronize()
    got = dy.copy_to_host()
    # float32 a*x+y rounded once (a fused multiply-add) or twice: within an ulp or two a step
    assert np.allclose(got, want, rtol=1e-5, atol=1e-6)
    assert not np.array_equal(got, y)
    assert step.converted == (not cuda_backend.simulated())


def test_a_host_array_goes_through_numba_cuda_each_time():
    """A host array is copied to the device and back by each launch: no
    conversion kept, or the copy would be made once only."""
    x = np.zeros(64, np.int32)
    step = Prepared(bump, 1, 64, x)
    step()
    step()
    assert (x == 3).all()
    assert not step.converted
