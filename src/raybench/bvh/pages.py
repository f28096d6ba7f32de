"""Rows reserved for a worst case and written in part, resident only where written."""

import mmap

import numpy as np

# Below this a reserve is plain NumPy memory: its huge pages are few, and
# faster to fault in than many small ones (measured: docs/triangles.md#memory).
SMALL_PAGES_FROM = 64 << 20


def reserve(rows: int, columns: int) -> np.ndarray:
    """(rows, columns) float32, unwritten. The host builder reserves a row a
    primitive for its subtrees' nodes and fills about two fifths of it; the
    4-wide collapse reserves a row a binary row and fills about a third.
    NumPy asks Linux for huge pages for a large array, and a 2 MiB page is
    made resident whole at its first write, so a large reserve would cost
    the process every row it might have written, not those it did: it is
    mapped in small pages. A slice of its first rows keeps only those rows
    resident, with no copy."""
    size = max(rows * columns, 1) * 4
    if size < SMALL_PAGES_FROM:
        return np.empty((rows, columns), np.float32)
    pages = mmap.mmap(-1, size)
    if hasattr(mmap, "MADV_NOHUGEPAGE"):  # Linux's; elsewhere pages are small unless asked
        pages.madvise(mmap.MADV_NOHUGEPAGE)
    return np.frombuffer(pages, np.float32)[: rows * columns].reshape(rows, columns)
