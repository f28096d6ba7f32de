"""What the benchmark scripts share: the common flags, rounds of variants taken in turn, medians
from raybench.bench.stats, and records in the results schema (raybench.bench.results), each
stamped with the run: the commit, the command and the machine. So `raybench report` reads what a
script writes, and a script is its setup and a timed call.

    parser = argparse.ArgumentParser(...)
    _harness.add_common(parser)                 # --frames, --rounds, --label, --out
    args = parser.parse_args()
    with _harness.Records("bvh_walks", args, settings={...}) as out:
        out.write(_harness.point("scaling", device, width, height, spheres, options, frames_ms, kernel_ms))

Records go to stdout, one JSON line each, and to --out (a .jsonl, appended) when given. Scripts
that measure something other than a suite's frames (builds, start-up, launches) cannot use the
schema yet; benchmarks/README.md lists which scripts use this harness and which do not.
"""

from __future__ import annotations

import argparse
import json
import sys
from collections.abc import Callable, Mapping

from raybench.bench import results
from raybench.bench.runner import run_info
from raybench.bench.stats import summarize
from raybench.machine import describe


def add_common(parser: argparse.ArgumentParser, frames: int = 9, rounds: int = 1) -> None:
    parser.add_argument("--frames", type=int, default=frames, help=f"timed frames a point (default {frames})")
    parser.add_argument(
        "--rounds", type=int, default=rounds, help=f"rounds of the variants, taken in turn (default {rounds})"
    )
    parser.add_argument("--label", help="the run's label in the records (default: the script's name)")
    parser.add_argument("--out", help="also append the records to this .jsonl")


def check_common(parser: argparse.ArgumentParser, args) -> None:
    for name in ("frames", "rounds"):
        if getattr(args, name) < 1:
            parser.error(f"--{name}: must be at least 1, got {getattr(args, name)}")
    if args.label is not None and not results.NAME.fullmatch(args.label):
        parser.error(f"--label: letters, digits, '.', '_' and '-', at most 64, got {args.label!r}")


def paired(variants: Mapping[str, Callable[[], float]], rounds: int) -> dict[str, list[float]]:
    """Each variant's samples over `rounds` rounds: a round calls every variant once, and the
    order turns round by round (a, b; b, a; ...), so a drift in the machine falls on both."""
    names = list(variants)
    samples: dict[str, list[float]] = {name: [] for name in names}
    for r in range(rounds):
        for name in names if r % 2 == 0 else names[::-1]:
            samples[name].append(variants[name]())
    return samples


def point(
    suite: str,
    device: str,
    width: int,
    height: int,
    spheres: int,
    options: dict,
    frames_ms: list[float],
    kernel_ms: list[float] | None = None,
    **measured,
) -> dict:
    """A point of the results schema from its frames' times (whole frames, and the kernel's own
    where the device times it): median, p5 and p95 from bench.stats, rays a second from the
    median. measured: any more of the schema's fields (build_s, first_frame_s, rays, ...)."""
    frame = summarize(frames_ms)
    kernel = summarize(kernel_ms) if kernel_ms else None
    return {
        "suite": suite,
        "test": None,
        "device": device,
        "width": width,
        "height": height,
        "spheres": spheres,
        "options": options,
        "frames": len(frames_ms),
        "frame_ms": frame,
        "kernel_ms": kernel,
        "rays_per_s": width * height / (frame["median"] / 1e3),
        "tests_per_s": None,
        **measured,
    }


class Records:
    """The records of one run of a script: each checked against the schema, stamped with the
    run, printed, and appended to --out."""

    def __init__(self, script: str, args, settings: dict):
        self.run = run_info(describe(), args.label or script, settings, argv=[f"benchmarks/{script}.py", *sys.argv[1:]])
        self.writer = results.ResultsWriter(args.out) if args.out else None

    def write(self, record: dict) -> None:
        record = {**record, "run": self.run}
        results.check_record({"format": results.FORMAT, "version": results.VERSION, **record}, "record")
        print(json.dumps({"format": results.FORMAT, "version": results.VERSION, **record}), flush=True)
        if self.writer is not None:
            self.writer.write(record)

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        if self.writer is not None:
            self.writer.close()
