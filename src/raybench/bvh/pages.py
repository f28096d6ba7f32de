"""Memory for the host builder's large arrays, mapped from the OS so that parts of it can be
resident only where written (reserve) or given back before the whole is let go (release)."""

import mmap

import numpy as np

# Below this a reserve is plain NumPy memory: its huge pages are few, and
# faster to fault in than many small ones (measured: docs/triangles.md#memory).
SMALL_PAGES_FROM = 64 << 20
# Below this a work array is plain NumPy memory, which release leaves alone: a small tree's
# arrays are not worth giving back in parts.
MAPPED_FROM = 4 << 20


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


def scratch(n: int, dtype) -> np.ndarray:
    """(n,) of dtype, unwritten, in mapped pages where it is large (huge pages asked for, as
    NumPy asks for them), so that release can give back its parts."""
    size = n * np.dtype(dtype).itemsize
    if size < MAPPED_FROM:
        return np.empty(n, dtype)
    pages = mmap.mmap(-1, size)
    if hasattr(mmap, "MADV_HUGEPAGE"):
        pages.madvise(mmap.MADV_HUGEPAGE)
    return np.frombuffer(pages, dtype)[:n]


def _mapping(array: np.ndarray):
    """The mmap under an array of reserve's or scratch's (through any views of it), or None."""
    owner = array.base
    while owner is not None and not isinstance(owner, mmap.mmap):
        # NumPy holds a buffer's exporter through a memoryview, whose obj it is
        owner = owner.obj if isinstance(owner, memoryview) else getattr(owner, "base", None)
    return owner


def mapped(array: np.ndarray) -> bool:
    """Whether release can give back parts of the array."""
    return hasattr(mmap, "MADV_DONTNEED") and _mapping(array) is not None


def release(array: np.ndarray, start: int, stop: int) -> None:
    """Give the OS back the whole pages of array[start:stop] (along its first axis, C-contiguous):
    what they held is lost (the builder reads none of it again). Nothing for an array in NumPy's
    memory (reserve's and scratch's small ones)."""
    pages = _mapping(array)
    if pages is None or not hasattr(mmap, "MADV_DONTNEED") or stop <= start:
        return
    row = array.strides[0]
    origin = np.frombuffer(pages, np.uint8).ctypes.data
    lo = array.ctypes.data - origin + start * row
    hi = array.ctypes.data - origin + stop * row
    lo, hi = -(-lo // mmap.PAGESIZE) * mmap.PAGESIZE, hi // mmap.PAGESIZE * mmap.PAGESIZE
    if hi > lo:
        pages.madvise(mmap.MADV_DONTNEED, lo, hi - lo)
