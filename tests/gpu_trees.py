"""What the tests of both GPU builders (numba-cuda's and WGSL's) compare
their trees with: the model of the GPU's tree, and the Morton codes worked
out bit by bit."""

import numpy as np


def tree_model():
    """raybench.bvh.lbvh_model: the GPU's tree built on the CPU, from the
    GPU builder's own steps (bvh/lbvh_steps.py) compiled by numba.njit."""
    from raybench.bvh import lbvh_model

    return lbvh_model


def morton_reference(spheres) -> np.ndarray:
    """Each centre's 30-bit Morton code in the centres' box, bit by bit:
    10 bits an axis, x highest."""
    n = spheres.shape[1]
    cells = np.zeros((3, n), np.int64)
    for a in range(3):
        c = spheres[a]
        lo, hi = c.min(), c.max()
        if hi > lo:
            cells[a] = np.minimum(((c - lo) * (np.float32(1024) / (hi - lo))).astype(np.int64), 1023)
    code = np.zeros(n, np.int64)
    for b in range(10):
        for a in range(3):
            code |= ((cells[a] >> b) & 1) << (3 * b + 2 - a)
    return code
