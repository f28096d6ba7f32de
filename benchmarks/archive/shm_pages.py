"""What a frame's shared memory costs before and after its pages are resident
(issue 17, docs/notes/scaling.md): a block the size of a --frame frame's image and
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

One record of the results schema's "parts" suite a way (quantity "shm-" and the way's name,
"shm-touch", "shm-copy-mapped", ...), with the block's bytes and the rate.

    PYTHONPATH=src:benchmarks python benchmarks/archive/shm_pages.py --frame 8192x8192 --frames 3
"""

from __future__ import annotations

import argparse
import mmap
import os
import re
import sys

import _harness
import numpy as np

from raybench.cluster import sharedframe

MADV_POPULATE_WRITE = 23  # linux/mman.h; Python 3.11's mmap module does not name it


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--frame", default="8192x8192")
    _harness.add_common(parser, frames=3)
    parser.add_argument("--repeat", dest="frames", type=int, help=argparse.SUPPRESS)  # its name before --frames
    args = parser.parse_args(argv)
    _harness.check_common(parser, args)
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

    out = _harness.Records("shm_pages", args, {"frame": args.frame})

    def report(name, times_ms):
        quantity = "shm-" + re.sub(r"[^a-z]+", "-", name).strip("-")
        rate = size / (_harness.median(times_ms) / 1e3) / 1e9
        out.write(_harness.part(quantity, "cpu", times_ms, width=width, height=height,
                                values={"bytes": size, "gb_per_s": rate}))  # fmt: skip

    first = {"touch": touch, "populate": populate, "fallocate": fallocate,
             "fallocate+populate": fallocate_populate, "madvise": madvise}  # fmt: skip
    for name, make in first.items():
        times = []
        for _ in range(args.frames * args.rounds):
            fd = new_file()
            try:
                times += _harness.timings(lambda fd=fd, make=make: make(fd), 1)
            finally:
                os.close(fd)
        report(name, times)

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
        times = _harness.paired({name: _harness.timed(f) for name, f in copies.items()}, args.frames * args.rounds)
        for name, samples in times.items():
            report(name, samples)

    try:
        with mapped(fd, True) as kept:
            resident(kept)
    finally:
        os.close(fd)
        out.close()
    return 0


if __name__ == "__main__":
    sys.exit(main())
