"""How soon Ctrl-C stops a long CPU frame: `raybench render` started in a session of its own,
SIGINT sent to its process group (as a terminal sends Ctrl-C) once a thread other than its main
one has run the frame's kernel for --after seconds of CPU time (the frame is under way, compiled
or loaded), and the seconds from the signal to the process's exit (exit code 130, nothing
written, one line are checked). One record of the results schema's "parts" suite (quantity
"interrupt-latency") a case, a sample a try; a case whose frame ends before it is caught is said
on stderr and left out.

    PYTHONPATH=src:benchmarks python benchmarks/archive/interrupt_latency.py --tries 3 --out out.jsonl
"""

from __future__ import annotations

import argparse
import os
import signal
import subprocess
import sys
import tempfile
import time

import _harness
import psutil

CASES = {
    "simple-10k-4096": ["--spheres", "10000", "--size", "4096x4096", "--accel", "none", "--kernel", "simple"],
    "whitted-2k-4096": ["--spheres", "2000", "--materials", "--shading", "whitted", "--size", "4096x4096"],
    "whitted-2k-4096-1thread": [
        "--spheres",
        "2000",
        "--materials",
        "--shading",
        "whitted",
        "--size",
        "4096x4096",
        "--threads",
        "1",
    ],  # fmt: skip
}


def under_way(pid: int, after: float) -> bool:
    try:
        return any(t.id != pid and t.user_time > after for t in psutil.Process(pid).threads())
    except psutil.NoSuchProcess:
        return False


def one(args: list[str], after: float) -> float | None:
    """Seconds from SIGINT to exit; None where the frame ended first."""
    with tempfile.TemporaryDirectory() as scratch, tempfile.TemporaryFile() as errors:
        out = os.path.join(scratch, "frame.png")
        argv = [sys.executable, "-m", "raybench", "render", *args, "--device", "cpu", "-o", out]
        proc = subprocess.Popen(argv, stdout=subprocess.DEVNULL, stderr=errors, start_new_session=True)
        try:
            deadline = time.monotonic() + 600
            while not under_way(proc.pid, after) and proc.poll() is None and time.monotonic() < deadline:
                time.sleep(0.05)
            if proc.poll() is not None:
                return None
            sent = time.monotonic()
            os.killpg(proc.pid, signal.SIGINT)
            proc.wait(timeout=120)
            took = time.monotonic() - sent
        finally:
            if proc.poll() is None:
                os.killpg(proc.pid, signal.SIGKILL)
                proc.wait(timeout=30)
        errors.seek(0)
        err = errors.read().decode().strip()
        assert proc.returncode == 130 and err == "raybench: interrupted" and not os.path.exists(out), (
            proc.returncode,
            err,
        )
        return took


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--case", action="append", choices=sorted(CASES), help="repeatable (default: every case)")
    parser.add_argument("--tries", type=int, default=3)
    parser.add_argument("--after", type=float, default=3.0, help="CPU seconds of a tracing thread before SIGINT")
    _harness.add_common(parser, frames=1, rounds=1)
    args = parser.parse_args(argv)
    _harness.check_common(parser, args)
    with _harness.Records("interrupt_latency", args, {"tries": args.tries, "after_s": args.after}) as records:
        for name in args.case or CASES:
            samples = [s for s in (one(CASES[name], args.after) for _ in range(args.tries)) if s is not None]
            if not samples:
                print(f"{name}: the frame ended before it was caught", file=sys.stderr)
                continue
            records.write(_harness.part("interrupt-latency", "cpu", [s * 1e3 for s in samples],
                                        options={"case": name}))  # fmt: skip
    return 0


if __name__ == "__main__":
    sys.exit(main())
