"""kernels/prefetch.py: the cache hint the cpu's packet walk gives ahead of its reads.

A hint changes no result (the frames' tests hold the walk to the float64
reference); these check that it is really emitted and that it is harmless
where the walk points it past an array's end (a leaf's second line fetched
for its last primitive).
"""

import numba
import numpy as np

from raybench.kernels.prefetch import prefetch


@numba.njit
def _sum_with_hints(values, ahead):
    total = 0.0
    for j in range(values.shape[1]):
        prefetch(values, 0, j + ahead)
        for i in range(values.shape[0]):
            total += values[i, j]
    return total


def test_the_hint_is_a_prefetch_in_the_machine_code():
    values = np.asfortranarray(np.arange(9 * 100, dtype=np.float32).reshape(9, 100))
    _sum_with_hints(values, 3)
    (signature,) = _sum_with_hints.signatures
    assert "@llvm.prefetch" in _sum_with_hints.inspect_llvm(signature)
    assert "prefetcht0" in _sum_with_hints.inspect_asm(signature)


def test_a_hint_past_the_end_changes_nothing():
    values = np.asfortranarray(np.random.default_rng(1).random((9, 1000)).astype(np.float32))
    expected = float(values.astype(np.float64).sum())
    # far past the end of the array, and before its start: a prefetch never faults
    for ahead in (0, 3, 1 << 20, -(1 << 20)):
        assert np.isclose(_sum_with_hints(values, ahead), expected, rtol=1e-5)
