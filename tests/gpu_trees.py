"""What the tests of both GPU builders (numba-cuda's and WGSL's) compare
their trees with: the model of the GPU's tree, and the Morton codes worked
out bit by bit."""

import importlib.util
from pathlib import Path

import numpy as np


def tree_model():
    """benchmarks/gpu_tree_model.py: the GPU's tree built on the CPU."""
    path = Path(__file__).parent.parent / "benchmarks" / "gpu_tree_model.py"
    spec = importlib.util.spec_from_file_location("gpu_tree_model", path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


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
