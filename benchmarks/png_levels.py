"""What zlib's level costs a sequence's PNG (issue 17): one frame traced, then
encoded as raybench encodes a sequence's frames (render.png_bytes, Pillow) at
each --level, the levels taken in turn round after round so that a busy
machine's noise falls on all of them alike. One line of JSON a level: the
median and fastest encode in ms, and the file's size.

    PYTHONPATH=src python benchmarks/png_levels.py --spheres 100000 --size 1680x1050 --rounds 7
"""

from __future__ import annotations

import argparse
import json
import statistics
import sys
import time

import raybench
from raybench import Camera
from raybench.render import png_bytes


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--spheres", type=int, default=100_000)
    parser.add_argument("--size", default="1680x1050")
    parser.add_argument("--device", default="cpu")
    parser.add_argument("--level", type=int, action="append", help="zlib levels (repeat; default 0 1 2 3 6 9)")
    parser.add_argument("--rounds", type=int, default=5)
    args = parser.parse_args(argv)
    width, height = (int(v) for v in args.size.lower().split("x"))
    # the multi-gpu benchmark's orbit starts here (benchmarks/multi_gpu.py)
    camera = Camera(position=(0, 0, -1), look_at=(0, 0, 2))
    image = raybench.render(raybench.random_spheres(args.spheres, seed=0), camera, width, height, args.device).image
    levels = args.level or [0, 1, 2, 3, 6, 9]
    times: dict[int, list[float]] = {level: [] for level in levels}
    sizes = {}
    for _ in range(args.rounds):
        for level in levels:
            start = time.perf_counter()
            sizes[level] = len(png_bytes(image, level))
            times[level].append(time.perf_counter() - start)
    for level in levels:
        print(json.dumps({"level": level, "spheres": args.spheres, "width": width, "height": height,
                          "encode_ms": statistics.median(times[level]) * 1e3, "fastest_ms": min(times[level]) * 1e3,
                          "bytes": sizes[level], "rounds": args.rounds}), flush=True)  # fmt: skip
    return 0


if __name__ == "__main__":
    sys.exit(main())
