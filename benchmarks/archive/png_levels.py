"""What zlib's level costs a sequence's PNG (issue 17): one frame traced, then encoded as
raybench encodes a sequence's frames (render.png_bytes, Pillow) at each --level, the levels taken
in turn round after round so that a busy machine's noise falls on all of them alike. One record
of the results schema's "parts" suite (quantity "png-encode") a level, with the file's size.

    PYTHONPATH=src:benchmarks python benchmarks/archive/png_levels.py --spheres 100000 --size 1680x1050 --rounds 7
"""

from __future__ import annotations

import argparse
import sys

import _harness

import raybench
from raybench import Camera
from raybench.render import png_bytes


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--spheres", type=int, default=100_000)
    parser.add_argument("--size", default="1680x1050")
    parser.add_argument("--device", default="cpu")
    parser.add_argument("--level", type=int, action="append", help="zlib levels (repeat; default 0 1 2 3 6 9)")
    _harness.add_common(parser, frames=1, rounds=5)
    args = parser.parse_args(argv)
    _harness.check_common(parser, args)
    width, height = (int(v) for v in args.size.lower().split("x"))
    # the multi-gpu benchmark's orbit starts here (benchmarks/multi_gpu.py)
    camera = Camera(position=(0, 0, -1), look_at=(0, 0, 2))
    image = raybench.render(raybench.random_spheres(args.spheres, seed=0), camera, width, height, args.device).image
    levels = args.level or [0, 1, 2, 3, 6, 9]
    sizes = {level: len(png_bytes(image, level)) for level in levels}
    variants = {level: _harness.timed(lambda level=level: png_bytes(image, level)) for level in levels}
    times = _harness.paired(variants, args.rounds * args.frames)
    with _harness.Records("png_levels", args, {"spheres": args.spheres, "size": args.size}) as out:
        for level in levels:
            out.write(
                _harness.part(
                    "png-encode", args.device, times[level], spheres=args.spheres, width=width, height=height,
                    options={"level": level}, values={"bytes": sizes[level]},
                )
            )  # fmt: skip
    return 0


if __name__ == "__main__":
    sys.exit(main())
