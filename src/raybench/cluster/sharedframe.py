"""A frame's image and hits in shared memory that is kept from frame to frame,
so that raybench.cluster's workers on the client's host write their tiles'
rows straight into the frame instead of sending them through Dask, and do not
pay for fresh pages every frame.

Why kept (docs/notes/scaling.md has the figures): on the machines measured, memory
first touched costs far more than the copy itself. Allocating a tmpfs page,
zeroing it and filling a page table entry for it in each process that maps it
runs several times slower than a copy into pages already mapped. So:

- The client's Pool makes a Block once per frame size: a file in /dev/shm,
  named after the client's process id (raybench-PID-...),
  its pages allocated at once (posix_fallocate, which also makes /dev/shm's
  lack of room an error here rather than a SIGBUS in a worker) and mapped here
  with their page tables filled (MAP_POPULATE).
- For each frame the block is lent (Pool.lease) under a fresh name, which the
  workers open, and renamed again as the frame ends: a task of an earlier
  frame finds no block. A block whose frame failed is not lent again (one of
  its tasks may still be writing) and its name is removed at once. The pool
  removes every name as it closes (the client's session ends; at exit for one
  left open). A client killed outright (SIGKILL, a crash) cannot: the first
  block that a later client makes removes the blocks of every raybench
  process that is gone (remove_stale), so at most one run's are left, and
  only until the next.
- A worker keeps its mapping of a block (write_rows, fill_rows), so its page
  tables are filled once, not every frame; a cuda worker page-locks it once
  too, and its GPU copies the rows into it directly.
- The frame handed back is arrays over the block, not a copy: a copy out into
  fresh memory costs what the block saves. The block goes back to its pool
  only when the last of those arrays is gone, so a frame the caller holds is
  never written again; a caller who holds one frame while the next is traced
  gets a second block, and the two take turns.

A worker on another host, or in another container, finds no file of that
name (it carries 64 random bits, so it is no other job's either) and
write_rows says so; its task then sends its rows as before.
"""

from __future__ import annotations

import atexit
import contextlib
import mmap
import os
import secrets
import threading
import weakref
from collections import OrderedDict

import numpy as np

PREFIX = "raybench-"  # every block's name starts so (tests look for leftovers by it)
_ALIGN = 64  # the hits start on a cache line
# Where Linux keeps POSIX shared memory, a file a block: workers open their
# client's block here. Elsewhere every tile is sent (write_rows says False).
SHM_DIR = "/dev/shm"
_POPULATE = getattr(mmap, "MAP_POPULATE", 0)  # Linux
# Idle blocks a pool keeps, and blocks a worker keeps mapped: two, so that a
# caller who holds each frame until the next one is traced (frame = render();
# frame.save()) finds the other block free every time.
KEEP_BLOCKS = 2


def _layout(width: int, height: int) -> tuple[int, int]:
    """(offset of the hits, size of the block) of a width x height frame."""
    image_bytes = height * width * 3
    offset = -(-image_bytes // _ALIGN) * _ALIGN
    return offset, offset + height * width * 4


def _views(buf, width: int, height: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(the whole block, image, hits) as arrays over buf; image and hits are
    views of the whole (their .base), so it lives as long as either does."""
    offset, size = _layout(width, height)
    whole = np.ndarray((size,), np.uint8, buffer=buf)
    image = whole[: height * width * 3].reshape(height, width, 3)
    hits = whole[offset:size].view(np.int32).reshape(height, width)
    return whole, image, hits


def room(size: int) -> bool:
    """Whether /dev/shm has size bytes free; without /dev/shm (not Linux)
    the workers could not open a block by its file, so none is made."""
    try:
        stat = os.statvfs(SHM_DIR)
    except OSError:
        return False
    return stat.f_bavail * stat.f_frsize >= size


def fits(width: int, height: int) -> bool:
    """Whether this host can make a width x height block now."""
    return room(_layout(width, height)[1])


def _fresh_name() -> str:
    return f"{PREFIX}{os.getpid()}-{secrets.token_hex(8)}"


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:  # another user's
        return True
    return True


def remove_stale() -> list[str]:
    """The blocks in /dev/shm of raybench clients that are gone (their
    process id, in the name, is no process's), this user's only, removed;
    their names. A live client's blocks are never touched."""
    removed = []
    try:
        names = os.listdir(SHM_DIR)
    except OSError:
        return removed
    for name in names:
        owner = name[len(PREFIX) :].split("-", 1)[0]
        if not (name.startswith(PREFIX) and owner.isdigit()) or _alive(int(owner)):
            continue
        path = os.path.join(SHM_DIR, name)
        with contextlib.suppress(OSError):  # gone meanwhile, or not ours
            if os.lstat(path).st_uid == os.geteuid():
                os.unlink(path)
                removed.append(name)
    return removed


_swept = False  # remove_stale ran in this process, as its first block was made


class Block:
    """A width x height frame's memory: a file in /dev/shm, its pages
    allocated and mapped here. Raises OSError where that cannot be (no room)."""

    def __init__(self, width: int, height: int):
        global _swept
        if not _swept:
            _swept = True
            remove_stale()
        self.width, self.height = width, height
        self.size = _layout(width, height)[1]
        self.retired = False  # its frame failed: not lent again
        self.name = _fresh_name()
        fd = os.open(self.path, os.O_RDWR | os.O_CREAT | os.O_EXCL, 0o600)
        try:
            os.ftruncate(fd, self.size)
            os.posix_fallocate(fd, 0, self.size)
            self._map = mmap.mmap(fd, self.size, flags=mmap.MAP_SHARED | _POPULATE)
        except BaseException:
            os.close(fd)
            os.unlink(self.path)
            raise
        self.fd = fd

    @property
    def path(self) -> str:
        return os.path.join(SHM_DIR, self.name)

    def rename(self) -> str:
        """A fresh name, atomically: a task that looks for the old one finds nothing."""
        new = _fresh_name()
        os.rename(self.path, os.path.join(SHM_DIR, new))
        self.name = new
        return new

    def unlink(self) -> None:
        """The name removed (again is harmless); the memory stays while it is mapped."""
        with contextlib.suppress(FileNotFoundError):
            os.unlink(self.path)

    def close(self) -> None:
        """The name removed and the file closed here; the memory goes with the
        last mapping of it (arrays over this one, a worker's)."""
        self.unlink()
        if self.fd is not None:
            os.close(self.fd)
            self.fd = None
        self._map = None  # unmapped by the mmap object itself, once no array needs it


class Lease:
    """A block lent to one frame: under a fresh name for the workers while the
    frame is traced, with image (H, W, 3 uint8) and hits (H, W int32) over it.
    The arrays stay valid after end(); the block returns to its pool when the
    last of them is gone."""

    def __init__(self, pool: Pool, block: Block):
        self.name = block.rename()
        self.width, self.height = block.width, block.height
        self._block = block
        whole, self.image, self.hits = _views(block._map, block.width, block.height)
        weakref.finalize(whole, pool._returned, block).atexit = False

    @property
    def address(self) -> tuple[str, int, int]:
        """What a task needs to find the block: (name, width, height)."""
        return self.name, self.width, self.height

    def end(self, ok: bool = True) -> None:
        """The frame is over, and its name goes: done, the block waits under
        another; failed or interrupted, a task may still write into it, so
        its name is removed and it is not lent again."""
        if ok and not self._block.retired:
            with contextlib.suppress(FileNotFoundError):  # a pool closed meanwhile removed it
                self._block.rename()
        else:
            self._block.retired = True
            self._block.unlink()


class Pool:
    """The blocks of one client's frames: kept between frames of one size
    (up to KEEP_BLOCKS idle), let go for another size or on close(). Every
    block's name is removed by close(), and at exit for a pool left open;
    only a process killed outright leaves its blocks in /dev/shm."""

    def __init__(self, keep: int = KEEP_BLOCKS):
        self.keep = keep
        self.made = 0  # blocks made, for the tests and the benchmark: 1 a session where frames are dropped in turn
        self._idle: list[Block] = []
        self._live: set[Block] = set()  # idle and lent: the names to remove on close
        self._size: tuple[int, int] | None = None
        self._closed = False
        self._lock = threading.Lock()  # _returned runs wherever the frame's last array dies
        _open_pools.add(self)

    def lease(self, width: int, height: int) -> Lease | None:
        """A block for one width x height frame: an idle one, else a new one;
        None where this host cannot give one (no /dev/shm, no room): the
        caller assembles the frame as before."""
        if self._closed:
            raise ValueError("the pool is closed")
        drop, block = [], None
        with self._lock:
            if self._size != (width, height):
                drop, self._idle, self._size = self._idle, [], (width, height)
            elif self._idle:
                block = self._idle.pop()
        for old in drop:
            self._close(old)
        if block is None:
            if not fits(width, height):
                return None
            try:
                block = Block(width, height)
            except OSError:
                return None
            self.made += 1
            with self._lock:
                self._live.add(block)
        try:
            return Lease(self, block)
        except BaseException:
            self._close(block)
            raise

    def can_lend(self, width: int, height: int) -> bool:
        """Whether lease(width, height) would lend a block kept idle, making none."""
        with self._lock:
            return not self._closed and self._size == (width, height) and bool(self._idle)

    def _returned(self, block: Block) -> None:
        """The last array over a lent block is gone: kept for the next frame,
        or closed."""
        with self._lock:
            keep = not (self._closed or block.retired) and self._size == (block.width, block.height)
            if keep and len(self._idle) < self.keep:
                self._idle.append(block)
                return
        self._close(block)

    def _close(self, block: Block) -> None:
        with self._lock:
            self._live.discard(block)
        block.close()

    @property
    def idle(self) -> int:
        return len(self._idle)

    def close(self) -> None:
        """Every block's name removed; idle blocks closed, a lent one once
        its frame's arrays are gone (they stay valid)."""
        with self._lock:
            self._closed, idle, self._idle = True, self._idle, []
            live = list(self._live)
        for block in live:
            block.unlink()
        for block in idle:
            self._close(block)
        _open_pools.discard(self)


_open_pools: weakref.WeakSet = weakref.WeakSet()


@atexit.register
def _close_pools() -> None:
    for pool in list(_open_pools):
        pool.close()


# --- on a worker --------------------------------------------------------------------

# The blocks this process keeps mapped, the last KEEP_BLOCKS it wrote into:
# (device, inode) -> [mmap, pin handle or None]. A block's file is the same
# from frame to frame under a new name each time, so its mapping, page tables
# filled (and page-locked for a device's direct copies, where pinned), is reused.
_mapped: OrderedDict = OrderedDict()
_mapped_lock = threading.Lock()


def write_rows(address: tuple[str, int, int], first: int, image: np.ndarray, hits: np.ndarray) -> bool:
    """Rows first.. of the frame at address (Lease.address) written from
    image and hits; False, and nothing written, where this process cannot
    open the block (another host, another container, not Linux, the frame
    is over). Writing the same rows again writes the same bytes (a retried task)."""
    _name, width, height = address
    rows = len(image)
    if image.shape != (rows, width, 3) or hits.shape != (rows, width):  # fill_rows checks where the rows lie
        raise ValueError(f"rows of shapes {image.shape}, {hits.shape}: not rows of a {width}x{height} frame")

    def copy(image_rows: np.ndarray, hit_rows: np.ndarray) -> None:
        image_rows[...] = image
        hit_rows[...] = hits

    return fill_rows(address, first, rows, copy)


def fill_rows(address: tuple[str, int, int], first: int, rows: int, fill, pin=None) -> bool:
    """Rows first..first + rows of the frame at address written by
    fill(image_rows, hit_rows), given this process's views of them in the
    block; False, and nothing written, where this process cannot open the
    block (as write_rows). pin(address, size), if given, is called once for
    each mapping, with where it lies in this process's memory, and what it
    returns is kept as long as the mapping is and dropped before it closes: a
    cuda worker page-locks the mapping there, so that the GPU copies its rows
    straight into the frame (cluster.tasks._tile)."""
    name, width, height = address
    offset, size = _layout(width, height)
    if not (0 <= first and 0 <= rows and first + rows <= height):
        raise ValueError(f"rows {first}..{first + rows}: not rows of a {width}x{height} frame")
    try:
        # The block's file, opened as itself: SharedMemory(name) would register
        # it with a resource tracker, one that an embedded cluster's workers
        # share with the client, and unlink or untrack the client's block.
        fd = os.open(os.path.join(SHM_DIR, name), os.O_RDWR)
    except OSError:  # not on this host, or the frame is over
        return False
    try:
        stat = os.fstat(fd)
        # Not a block of this size; or its pages not all allocated, where a
        # write to a missing one with /dev/shm full would die of SIGBUS.
        if stat.st_size != size or stat.st_blocks * 512 < size:
            return False
        with _mapped_lock:
            mapped = _mapping(fd, (stat.st_dev, stat.st_ino), size, pin)
            _fill(mapped, width, height, first, rows, fill)
        return True
    finally:
        os.close(fd)


def _mapping(fd: int, key: tuple[int, int], size: int, pin) -> mmap.mmap:
    """This process's mapping of the block open at fd: the kept one, or a new
    one with its page tables filled at once (MAP_POPULATE: several times
    faster than faulting its pages in one by one as a copy touches them),
    pinned by pin where given and not pinned yet."""
    held = _mapped.get(key)
    if held is None:
        held = _mapped[key] = [mmap.mmap(fd, size, flags=mmap.MAP_SHARED | _POPULATE), None]
        while len(_mapped) > KEEP_BLOCKS:
            _unmap(_mapped.popitem(last=False)[1])
    if pin is not None and held[1] is None:
        held[1] = pin(*_address(held[0]))
    _mapped.move_to_end(key)
    return held[0]


def _address(mapped: mmap.mmap) -> tuple[int, int]:
    # through a view that is gone when this returns: a mapping cannot close under one
    view = np.frombuffer(mapped, np.uint8)
    return view.ctypes.data, view.nbytes


def _unmap(held: list) -> None:
    held[1] = None  # unpinned (the pin's object dropped) before the memory goes
    held[0].close()


def mapped_blocks() -> int:
    """How many blocks this process keeps mapped (at most KEEP_BLOCKS)."""
    with _mapped_lock:
        return len(_mapped)


def forget() -> int:
    """Every block this process keeps mapped let go (its memory is freed once
    the client's frames of it are gone too); how many. The client's session
    asks its workers so as it closes."""
    with _mapped_lock:
        count = len(_mapped)
        while _mapped:
            _unmap(_mapped.popitem()[1])
    return count


def _fill(mapped: mmap.mmap, width: int, height: int, first: int, rows: int, fill) -> None:
    # a function of its own, so that its views of the mapping are gone, even
    # when it raises, before the mapping is closed (closing under a view fails)
    _whole, image, hits = _views(mapped, width, height)
    fill(image[first : first + rows], hits[first : first + rows])
