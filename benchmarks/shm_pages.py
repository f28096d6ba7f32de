"""What a frame's shared memory costs before and after its pages are resident
(issue 17, docs/scaling.md): a block the size of a --frame frame's image and
hits (7 bytes a pixel) in /dev/shm, made each of the ways Python allows, and
then the copies a frame costs once it is made.

First touch, a new block each time (what a frame costs when its block is new):
  touch             mapped, then written by NumPy: every page faulted in from user space
  populate          mapped with MAP_POPULATE: allocated and its page tables filled by the kernel
  fallocate         posix_fallocate: allocated and zeroed, not mapped (what sharedframe.Block does first)
  fallocate+populate  both (sharedframe.Block: allocated, then mapped here with page tables filled)
  madvise           mapped, then madvise(MADV_POPULATE_WRITE) (Linux 5.14)

Once resident:
  copy, mapped      a frame's rows copied into pages mapped here already (a worker's kept mapping)
  copy, map lazily  mapped afresh without MAP_POPULATE, then copied: pages present, page tables not
  copy, map+populate  mapped afresh with MAP_POPULATE, then copied (a worker's first frame of a block)
  copy out          the frame copied out of the block into new memory (what a copy a frame would cost)

    PYTHONPATH=src python benchmarks/shm_pages.py --frame 8192x8192 --repeat 3
"""

from __future__ import annotations

import argparse
import json
import mmap
import os
import statistics
import sys
import time

import numpy as np

from raybench.cluster import sharedframe

MADV_POPULATE_WRITE = 23  # linux/mman.h; Python 3.11's mmap module does not name it


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--frame", default="8192x8192")
    parser.add_argument("--repeat", type=int, default=3)
    args = parser.parse_args(argv)
    width, height = (int(v) for v in args.frame.lower().split("x"))
    size = width * height * 7
    if not sharedframe.room(2 * size):
        raise SystemExit(f"{sharedframe.SHM_DIR}: no room for two {args.frame} blocks")

    def new_file() -> int:
        fd = os.open(sharedframe.SHM_DIR, os.O_TMPFILE | os.O_RDWR, 0o600)  # no name: nothing left behind
        os.ftruncate(fd, size)
        return fd

    def mapped(fd: int, populate: bool = False) -> mmap.mmap:
        return mmap.mmap(fd, size, flags=mmap.MAP_SHARED | (mmap.MAP_POPULATE if populate else 0))

    def touch(fd):
        with mapped(fd) as m:
            np.frombuffer(m, np.uint8)[:] = 0

    def populate(fd):
        mapped(fd, True).close()

    def fallocate(fd):
        os.posix_fallocate(fd, 0, size)

    def fallocate_populate(fd):
        os.posix_fallocate(fd, 0, size)
        mapped(fd, True).close()

    def madvise(fd):
        with mapped(fd) as m:
            m.madvise(MADV_POPULATE_WRITE)

    def report(name, seconds):
        median = statistics.median(seconds)
        print(json.dumps({"what": name, "frame": args.frame, "bytes": size, "median_ms": median * 1e3,
                          "fastest_ms": min(seconds) * 1e3, "gb_per_s": size / median / 1e9,
                          "repeat": len(seconds)}), flush=True)  # fmt: skip

    first = {"touch": touch, "populate": populate, "fallocate": fallocate,
             "fallocate+populate": fallocate_populate, "madvise": madvise}  # fmt: skip
    for name, make in first.items():
        seconds = []
        for _ in range(args.repeat):
            fd = new_file()
            try:
                start = time.perf_counter()
                make(fd)
                seconds.append(time.perf_counter() - start)
            finally:
                os.close(fd)
        report(name, seconds)

    fd = new_file()
    os.posix_fallocate(fd, 0, size)
    rows = np.ones(size, np.uint8)  # a worker's rows, as its tracer leaves them

    def copy_fresh(populate):
        with mapped(fd, populate) as m:
            np.frombuffer(m, np.uint8)[:] = rows

    def resident(kept: mmap.mmap) -> None:
        # a function of its own: its arrays over the mapping are gone before the mapping is closed
        block = np.frombuffer(kept, np.uint8)
        copies = {
            "copy, mapped": lambda: np.copyto(block, rows),
            "copy, map lazily": lambda: copy_fresh(False),
            "copy, map+populate": lambda: copy_fresh(True),
            "copy out": lambda: block.copy(),
        }
        for name, f in copies.items():
            seconds = []
            for _ in range(args.repeat):
                start = time.perf_counter()
                f()
                seconds.append(time.perf_counter() - start)
            report(name, seconds)

    try:
        with mapped(fd, True) as kept:
            resident(kept)
    finally:
        os.close(fd)
    return 0


if __name__ == "__main__":
    sys.exit(main())
