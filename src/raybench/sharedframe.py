"""A frame's image and hits in one named block of shared memory, so that
raybench.cluster's workers on the client's host write their tiles' rows
straight into the frame instead of sending them through Dask.

The client creates the block (create), the workers attach it by name
(write_rows), and the client unlinks the name as soon as the job ends, done or
failed: the mapping stays valid without the name, so the frame's arrays
outlive the job and nothing is left in /dev/shm. The block's memory is
unmapped when the last of those arrays is garbage-collected.

A worker on another host, or in another container, finds no block of that
name (the name carries 64 random bits, so it is no other job's either) and
write_rows says so; its task then sends its rows as before. So does one
where /dev/shm has no room left for its rows.
"""

from __future__ import annotations

import contextlib
import mmap
import os
import secrets
import weakref
from multiprocessing.shared_memory import SharedMemory

import numpy as np

PREFIX = "raybench-"  # every block's name starts so (tests look for leftovers by it)
_ALIGN = 64  # the hits start on a cache line
# Where Linux keeps POSIX shared memory, a file a block: workers open their
# client's block here. Elsewhere every tile is sent (write_rows says False).
SHM_DIR = "/dev/shm"
_POPULATE = getattr(mmap, "MAP_POPULATE", 0)  # Linux


def _layout(width: int, height: int) -> tuple[int, int]:
    """(offset of the hits, size of the block) of a width x height frame."""
    image_bytes = height * width * 3
    offset = -(-image_bytes // _ALIGN) * _ALIGN
    return offset, offset + height * width * 4


def _views(buf, width: int, height: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(the whole block, image, hits) as arrays over buf."""
    offset, size = _layout(width, height)
    whole = np.ndarray((size,), np.uint8, buffer=buf)
    image = whole[: height * width * 3].reshape(height, width, 3)
    hits = whole[offset:size].view(np.int32).reshape(height, width)
    return whole, image, hits


def _room(size: int) -> bool:
    """Whether /dev/shm has size bytes free: a block is sparse, and one that
    would not fit is better not begun. Without /dev/shm (not Linux) the
    workers could not open a block by its file, so none is made."""
    try:
        stat = os.statvfs(SHM_DIR)
    except OSError:
        return False
    return stat.f_bavail * stat.f_frsize >= size


class SharedFrame:
    """A width x height frame's image (H, W, 3 uint8) and hits (H, W int32)
    in a shared block created here. image and hits are NumPy arrays over it;
    they keep the memory mapped for as long as either is alive."""

    def __init__(self, width: int, height: int):
        _, size = _layout(width, height)
        self.name = f"{PREFIX}{os.getpid()}-{secrets.token_hex(8)}"
        self.width, self.height = width, height
        self._shm = SharedMemory(name=self.name, create=True, size=size)
        whole, self.image, self.hits = _views(self._shm.buf, width, height)
        # Closed (unmapped) when the last view of the block dies, not before:
        # closing while a view is exported would fail, and so would the view.
        weakref.finalize(whole, self._shm.close).atexit = False

    @property
    def address(self) -> tuple[str, int, int]:
        """What a task needs to attach the block: (name, width, height)."""
        return self.name, self.width, self.height

    def unlink(self) -> None:
        """Remove the block's name (again is harmless); the arrays stay valid."""
        with contextlib.suppress(FileNotFoundError):
            self._shm.unlink()


def fits(width: int, height: int) -> bool:
    """Whether this host can make a width x height SharedFrame now."""
    return _room(_layout(width, height)[1])


def create(width: int, height: int) -> SharedFrame | None:
    """A SharedFrame, or None where this host cannot give one (no room in
    /dev/shm, or no /dev/shm): the caller assembles as before."""
    if not fits(width, height):
        return None
    try:
        return SharedFrame(width, height)
    except OSError:
        return None


def write_rows(address: tuple[str, int, int], first: int, image: np.ndarray, hits: np.ndarray) -> bool:
    """Rows first.. of the frame at address (SharedFrame.address) written
    from image and hits; False, and nothing written, where this process
    cannot open the block (another host, another container, not Linux) or
    it has no room. Writing the same rows again writes the same bytes (a
    retried task)."""
    name, width, height = address
    offset, size = _layout(width, height)
    rows = len(image)
    if not (0 <= first and first + rows <= height and image.shape == (rows, width, 3) and hits.shape == (rows, width)):
        raise ValueError(
            f"rows {first}..{first + rows} ({image.shape}, {hits.shape}): not rows of a {width}x{height} frame"
        )
    try:
        # The block's file, opened as itself: SharedMemory(name) would register
        # it with a resource tracker, one that an embedded cluster's workers
        # share with the client, and unlink or untrack the client's block.
        fd = os.open(os.path.join(SHM_DIR, name), os.O_RDWR)
    except OSError:  # not on this host, or the job is over
        return False
    try:
        if os.fstat(fd).st_size != size:
            return False
        for start, rows_array in ((first * width * 3, image), (offset + first * width * 4, hits)):
            if not _write(fd, start, rows_array):
                return False
        return True
    finally:
        os.close(fd)


def _write(fd: int, start: int, rows_array: np.ndarray) -> bool:
    """rows_array's bytes at byte start of the block: its pages reserved first
    (the block is sparse: a write to a page that tmpfs has no room for dies of
    SIGBUS; a reservation that fails says so), then mapped with their page
    tables filled at once, rather than page by page as the copy touches them."""
    length = rows_array.nbytes
    try:
        os.posix_fallocate(fd, start, length)
    except OSError:  # ENOSPC: /dev/shm is full
        return False
    base = start - start % mmap.ALLOCATIONGRANULARITY
    with mmap.mmap(fd, start + length - base, flags=mmap.MAP_SHARED | _POPULATE, offset=base) as mapped:
        _copy_into(mapped, start - base, rows_array)
    return True


def _copy_into(mapped: mmap.mmap, at: int, rows_array: np.ndarray) -> None:
    # a function of its own, so that its view of the mapping is gone, even
    # when it raises, before the mapping is closed (closing under a view fails)
    np.frombuffer(mapped, np.uint8, rows_array.nbytes, at)[:] = rows_array.reshape(-1).view(np.uint8)
