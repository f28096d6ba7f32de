"""What the benchmark scripts share: the common flags, rounds of variants taken in turn, medians
from raybench.bench.stats, and records in the results schema (raybench.bench.results), each
stamped with the run: the commit, the command and the machine. So `raybench report` reads what a
script writes, and a script is its setup and a timed call.

    parser = argparse.ArgumentParser(...)
    _harness.add_common(parser)                 # --frames, --rounds, --label, --out
    args = parser.parse_args()
    with _harness.Records("bvh_walks", args, settings={...}) as out:
        out.write(_harness.point("scaling", device, width, height, spheres, options, frames_ms, kernel_ms))

What is no suite's frame (a build, a start-up, a launch, a part of a frame) is a record of the
schema's "parts" suite, made by part():

    with _harness.Records("bvh_build", args, settings={...}) as out:
        out.write(_harness.part("bvh-build", "cpu", _harness.timings(build, args.frames), spheres=n))

Records go to stdout, one JSON line each, and to --out (a .jsonl, appended) when given.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time
from collections.abc import Callable, Mapping

import raybench
from raybench.bench import results
from raybench.bench.runner import run_info
from raybench.bench.stats import kept_samples, summarize
from raybench.machine import describe

# glibc's threshold over which an allocation is mapped from the OS on its own, fixed (its default
# rises, up to 32 MiB, as large blocks are freed, and then blocks under it are carved from memory
# the process already holds, which its resident set does not show)
MMAP_THRESHOLD = "131072"


def own_pages() -> None:
    """Run this script again, once, with glibc's mmap threshold fixed, so that the resident set
    counts every large array a measurement makes. Without it arrays under the threshold's ceiling
    can be carved from memory the process already holds, and go uncounted
    (docs/notes/mesh-memory.md)."""
    if sys.platform.startswith("linux") and os.environ.get("MALLOC_MMAP_THRESHOLD_") != MMAP_THRESHOLD:
        os.execve(sys.executable, [sys.executable, *sys.argv], {**os.environ, "MALLOC_MMAP_THRESHOLD_": MMAP_THRESHOLD})


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


def paired(variants: Mapping, rounds: int) -> dict:
    """Each variant's samples over `rounds` rounds: a round calls every variant once, and the
    order turns round by round (a, b; b, a; ...), so a drift in the machine falls on both. A
    variant returns one sample, or a list of them (several frames in its turn)."""
    names = list(variants)
    samples: dict = {name: [] for name in names}
    for r in range(rounds):
        for name in names if r % 2 == 0 else names[::-1]:
            got = variants[name]()
            samples[name].extend(got if isinstance(got, list) else [got])
    return samples


def median(samples: list[float]) -> float:
    """The median of samples, as bench.stats gives it (a ratio's terms, a share)."""
    return summarize(samples)["median"]


def timings(call: Callable[[], object], times: int) -> list[float]:
    """call() timed `times` times, one after another: the wall-clock milliseconds of each."""
    out = []
    for _ in range(times):
        start = time.perf_counter()
        call()
        out.append((time.perf_counter() - start) * 1e3)
    return out


def timed(call: Callable[[], object]) -> Callable[[], float]:
    """call as a variant of paired(): it returns the milliseconds that one call took."""
    return lambda: timings(call, 1)[0]


def part(
    quantity: str,
    device: str,
    times_ms: list[float],
    *,
    spheres: int | None = None,
    width: int | None = None,
    height: int | None = None,
    options: dict | None = None,
    values: dict | None = None,
) -> dict:
    """A record of the "parts" suite (raybench.bench.results.PART): a quantity timed apart from
    any suite's frames, its median, p5 and p95 from bench.stats; values: other figures measured
    with it, by name (numbers or None)."""
    record = {"suite": "parts", "quantity": quantity, "device": device, "samples": len(times_ms)}
    for key, value in (("spheres", spheres), ("width", width), ("height", height)):
        if value is not None:
            record[key] = value
    record["options"] = {key: value for key, value in (options or {}).items() if value is not None}
    record["time_ms"] = summarize(times_ms)
    record["samples_ms"] = kept_samples(times_ms)
    if values:
        record["values"] = values
    return record


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
        "samples_ms": kept_samples(frames_ms),
        "kernel_ms": kernel,
        "rays_per_s": width * height / (frame["median"] / 1e3),
        "tests_per_s": None,
        **measured,
    }


class Records:
    """The records of one run of a script: each checked against the schema, stamped with the
    run, printed, and appended to --out."""

    def __init__(self, script: str, args, settings: dict):
        settings = {**settings, "raybench": raybench.__file__}  # which source tree ran (A/B runs)
        self.run = run_info(describe(), args.label or script, settings, argv=[f"benchmarks/{script}.py", *sys.argv[1:]])
        self.writer = results.ResultsWriter(args.out) if args.out else None

    def write(self, record: dict) -> None:
        record = {**record, "run": self.run}
        results.check_record({"format": results.FORMAT, "version": results.VERSION, **record}, "record")
        print(json.dumps({"format": results.FORMAT, "version": results.VERSION, **record}), flush=True)
        if self.writer is not None:
            self.writer.write(record)

    def close(self) -> None:
        if self.writer is not None:
            self.writer.close()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()
