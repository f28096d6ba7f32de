"""`raybench compare` at scale: two results files of --points points each (every point with
--samples kept frame times, a share --unmatched measured with other options in the second file),
compared by a fresh `python -m raybench compare` process --rounds times; each round's wall time,
the process's CPU time (user + system: on a shared machine, what the wall time is not) and peak
resident memory, and the load average as each round starts. Issue 39's target: 10,000 points against 10,000 in under
10 s and under 500 MB on the 2-vCPU machine.

    PYTHONPATH=src:benchmarks python benchmarks/archive/compare_scale.py --points 10000 --samples 100 --rounds 3
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import _harness
import numpy as np

from raybench.bench import results
from raybench.bench.stats import kept_samples, summarize


def records(n: int, samples: int, unmatched: float, slowdown: float, rng):
    """n thesis points of `samples` frames each (3% log-normal jitter, a stalled frame in 20),
    the first `unmatched` share with 8 threads in place of 2. One at a time: a process holding
    them all would lend its size to each compare it forks (the child's peak counts the parent's
    pages until exec)."""
    run = {"id": "scale", "date": "2026-12-03T00:00:00+00:00", "label": "scale", "machine": {"gpus": []}}
    for i in range(n):
        t = (5.0 + i % 50) * rng.lognormal(0.0, 0.03, samples) * slowdown
        t[rng.random(samples) < 0.05] *= 1.4
        threads = 8 if slowdown != 1.0 and i < unmatched * n else 2
        yield (
            {"format": results.FORMAT, "version": results.VERSION, "suite": "thesis", "test": 4, "device": "cpu",
             "width": 800, "height": 600, "spheres": 100 + i, "options": {"accel": "bvh", "threads": threads},
             "frames": samples, "frame_ms": summarize(t), "samples_ms": kept_samples(t), "kernel_ms": None, "run": run}
        )  # fmt: skip


def one_compare(old: Path, new: Path) -> tuple[float, float, float, str]:
    """The wall time (ms), CPU time (s) and peak resident memory (MB) of one `raybench compare`,
    and its last line."""
    with tempfile.TemporaryFile() as out, tempfile.TemporaryFile() as err:
        start = time.perf_counter()
        argv = [sys.executable, "-m", "raybench", "compare", str(old), str(new)]
        proc = subprocess.Popen(argv, stdout=out, stderr=err)
        _, status, usage = os.wait4(proc.pid, 0)  # this child's own rusage: its peak memory
        wall_ms = (time.perf_counter() - start) * 1e3
        proc.returncode = os.waitstatus_to_exitcode(status)
        out.seek(0)
        err.seek(0)
        if proc.returncode != 0:
            raise SystemExit(f"compare failed ({proc.returncode}): {err.read().decode()[-500:]}")
        cpu_s = usage.ru_utime + usage.ru_stime
        return wall_ms, cpu_s, usage.ru_maxrss / 1024, out.read().decode().strip().splitlines()[-1]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--points", type=int, default=10_000)
    parser.add_argument("--samples", type=int, default=100, help="kept frame times a point (at most 1,000)")
    parser.add_argument("--unmatched", type=float, default=0.1, help="share of points measured differently")
    _harness.add_common(parser, rounds=3)
    args = parser.parse_args()
    _harness.check_common(parser, args)
    rng = np.random.default_rng(0)
    with tempfile.TemporaryDirectory() as folder, _harness.Records("compare_scale", args, settings=vars(args)) as out:
        paths = []
        for name, slowdown in (("old", 1.0), ("new", 1.02)):
            path = Path(folder) / f"{name}.jsonl"
            with path.open("w") as f:
                for r in records(args.points, args.samples, args.unmatched, slowdown, rng):
                    f.write(json.dumps(r) + "\n")
            paths.append(path)
        walls, cpus, peaks, loads = [], [], [], []
        for _ in range(args.rounds):
            loads.append(os.getloadavg()[0])
            wall, cpu, peak, last = one_compare(*paths)
            walls.append(wall)
            cpus.append(cpu)
            peaks.append(peak)
            print(f"compare: {wall / 1e3:.2f} s, CPU {cpu:.2f} s, peak {peak:.0f} MB, load {loads[-1]:.2f}; {last}",
                  file=sys.stderr)  # fmt: skip
        values = {"points": args.points, "samples": args.samples, "peak_rss_mb": max(peaks),
                  "file_mb": paths[0].stat().st_size / 1e6, "cpu_s_min": min(cpus), "cpu_s_max": max(cpus),
                  "load_1m_min": min(loads), "load_1m_max": max(loads)}  # fmt: skip
        out.write(_harness.part("compare", "cpu", walls, options={"label": f"{args.points} points"}, values=values))


if __name__ == "__main__":
    main()
