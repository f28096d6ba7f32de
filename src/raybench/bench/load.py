"""Was the machine busy with other work during a run? A benchmark on a shared machine reads
low and varies from run to run (issue 40: 5.0 to 7.6 M rays/s on one 2-vCPU machine), and no
interval over one run's frames can see it. So the run counts the CPU time that other
processes took while it ran: the whole machine's busy time, less this process's and its
children's (the multi-gpu suite's workers among them)."""

from __future__ import annotations

import time

import psutil

# Other processes' share of the machine's CPU time past which the run is called loaded: a
# tenth of it is most of a core on a 2-vCPU machine, enough to move a brute-force frame.
LOADED = 0.10


def _busy(times) -> float:
    idle = times.idle + getattr(times, "iowait", 0.0)
    return sum(times) - idle - getattr(times, "guest", 0.0) - getattr(times, "guest_nice", 0.0)


def _own(process: psutil.Process) -> float:
    t = process.cpu_times()
    total = t.user + t.system + t.children_user + t.children_system
    for child in process.children(recursive=True):
        try:
            c = child.cpu_times()
        except (psutil.NoSuchProcess, psutil.AccessDenied):
            continue
        total += c.user + c.system
    return total


class Load:
    """Start it before the work; others() after it: other processes' share of the CPU time."""

    def __init__(self):
        self.process = psutil.Process()
        self.cpus = psutil.cpu_count() or 1
        self.wall = time.monotonic()
        self.busy = _busy(psutil.cpu_times())
        self.own = _own(self.process)

    def others(self) -> float:
        wall = time.monotonic() - self.wall
        if wall <= 0:
            return 0.0
        other = (_busy(psutil.cpu_times()) - self.busy) - (_own(self.process) - self.own)
        return min(1.0, max(0.0, other) / (wall * self.cpus))  # clock ticks can overshoot a whole machine


def warning(share: float) -> str | None:
    """The line bench prints when other processes took more than LOADED of the machine."""
    if share <= LOADED:
        return None
    return (
        f"warning: the machine was loaded: other processes took {share:.0%} of its CPU time during this run; "
        "the figures above may read low and vary from run to run more than their intervals say"
    )
