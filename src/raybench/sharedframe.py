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
write_rows says so; its task then sends its rows as before.
"""

from __future__ import annotations

import contextlib
import os
import secrets
import weakref
from multiprocessing import resource_tracker
from multiprocessing.shared_memory import SharedMemory

import numpy as np

PREFIX = "raybench-"  # every block's name starts so (tests look for leftovers by it)
_ALIGN = 64  # the hits start on a cache line


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
    """Whether /dev/shm (where Linux keeps the blocks) has size bytes free. A
    block is created sparse: were the room short, a worker's write would die
    of SIGBUS, and Dask would retry it until the job failed."""
    try:
        stat = os.statvfs("/dev/shm")
    except OSError:  # not Linux: the system has no such file system to fill
        return True
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


def create(width: int, height: int) -> SharedFrame | None:
    """A SharedFrame, or None where this host cannot give one (no room in
    /dev/shm, no shared memory at all): the caller assembles as before."""
    if not _room(_layout(width, height)[1]):
        return None
    try:
        return SharedFrame(width, height)
    except OSError:
        return None


def write_rows(address: tuple[str, int, int], first: int, image: np.ndarray, hits: np.ndarray) -> bool:
    """Rows first.. of the frame at address (SharedFrame.address) written
    from image and hits; False, and nothing written, where this process
    cannot open the block (another host) or it is not a frame of this size.
    Writing the same rows again writes the same bytes (a retried task)."""
    name, width, height = address
    try:
        shm = SharedMemory(name=name)
    except OSError:  # FileNotFoundError: not on this host, or the job is over
        return False
    # Python < 3.13 registers an attached block with this process's resource
    # tracker, which would unlink the client's block when this worker exits.
    with contextlib.suppress(Exception):
        resource_tracker.unregister(shm._name, "shared_memory")
    try:
        if shm.size < _layout(width, height)[1]:
            return False
        _copy(shm.buf, width, height, first, image, hits)
        return True
    finally:
        shm.close()


def _copy(buf, width: int, height: int, first: int, image: np.ndarray, hits: np.ndarray) -> None:
    # a function of its own, so that its views of the block are gone, even
    # when it raises, before the block is closed (closing under a view fails)
    _, frame_image, frame_hits = _views(buf, width, height)
    frame_image[first : first + len(image)] = image
    frame_hits[first : first + len(hits)] = hits
