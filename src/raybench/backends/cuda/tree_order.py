"""A scene's buffer put in its tree's order on the device, a row at a time:
what cuda's walks read as their leaves and its shading reads as the scene,
for a kind traced so (program.in_tree_order)."""

from __future__ import annotations

import math

import numpy as np
from numba import cuda

from ... import compiled

BLOCK = 256


@compiled.cuda_jit()
def _gather_row(source, order, out, row):
    """out[row, k] = source[order[k]]: a row of the buffer in the tree's order."""
    k = cuda.grid(1)
    if k < order.shape[0]:
        out[row, k] = source[order[k]]


# Columns a row of a buffer with a column after its primitives is rounded up to: 128 bytes, so
# that every row starts where a warp's coalesced read of 32 float32 meets one cache line, not two.
ROW_COLUMNS = 32


@compiled.cuda_jit()
def _put_columns(column, out, first):
    """out[r, c] = column[r, 0] for every row r and every column c from first on."""
    c, r = cuda.grid(2)
    if r < out.shape[0] and first + c < out.shape[1]:
        out[r, first + c] = column[r, 0]


def in_tree_order(rows: np.ndarray, d_order, count: int, d_rows=None, last=None):
    """The first `count` columns of the (R, N) float32 buffer `rows` on the
    device in the tree's order d_order (the original index of each of the
    tree's count columns), made from d_rows (rows' copy on the device) where
    given, else from rows copied up a row at a time: beside the result the
    device then holds one row more, not the whole buffer again. last: a
    column of float32 put after the tree's columns, in every column up to a
    whole ROW_COLUMNS, with the buffer's first rows alone, as many as the
    column's (a mesh's one colour, read from the last column: the triangle's
    shared_colour). With none, a column of zeros, as the tracer's stand-ins."""
    kept = rows.shape[0] if last is None else last.shape[0]
    if count == 0:
        return cuda.to_device(np.zeros((kept, 1), np.float32))
    columns = count if last is None else -(-(count + 1) // ROW_COLUMNS) * ROW_COLUMNS
    out = cuda.device_array((kept, columns), np.float32)
    grid = math.ceil(count / BLOCK)
    one = None if d_rows is not None else cuda.device_array(count, np.float32)
    for r in range(kept):
        if d_rows is None:
            one.copy_to_device(np.ascontiguousarray(rows[r, :count]))
            source = one
        else:
            source = d_rows[r]
        _gather_row[grid, BLOCK](source, d_order, out, r)
    if last is not None:
        _put_columns[(1, kept), (ROW_COLUMNS, 1)](cuda.to_device(np.ascontiguousarray(last, np.float32)), out, count)
    cuda.synchronize()
    return out
