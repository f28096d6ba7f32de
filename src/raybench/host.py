"""What this process may use of its host: its cores and its memory. Read by
the lowest layers (the builder, the backends, the scene's checks), so it
imports nothing of raybench; machine.py describes the machine for records."""

from __future__ import annotations

import os

import psutil

try:
    import resource  # Unix only: the ulimits below
except ImportError:
    resource = None


def usable_cores() -> int:
    """The cores this process may run on: its affinity (taskset, a
    container's cpuset), not the machine's count."""
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # not on Linux
        return os.cpu_count() or 1


# A thread's stack where RLIMIT_STACK sets none: glibc's default on x86-64 and arm64.
DEFAULT_STACK_BYTES = 8 * 2**20


def thread_stack_bytes() -> int:
    """The address space a new thread reserves for its stack: Python's
    threading.stack_size() where set, else RLIMIT_STACK's soft limit, as
    glibc's threads take it."""
    import threading

    chosen = threading.stack_size()
    if chosen:
        return chosen
    if resource is None:  # Windows: no such limit, and a thread's stack is reserved as its own
        return DEFAULT_STACK_BYTES
    soft = resource.getrlimit(resource.RLIMIT_STACK)[0]
    return DEFAULT_STACK_BYTES if soft == resource.RLIM_INFINITY else soft


def host_available_bytes(threads: int = 0) -> int:
    """What this process may still allocate: the free memory, or less where a
    ulimit (address space, data) or the cgroup's memory limit leaves less.
    Beyond it an allocation ends in a MemoryError or the OOM killer.

    threads: the threads the work will start. Under an address-space limit
    (ulimit -v) each one's stack counts against it, untouched or not: a
    frame that fitted without them failed with "can't start new thread"."""
    available = psutil.virtual_memory().available
    memory = psutil.Process().memory_info()
    stacks = threads * thread_stack_bytes()
    limits = (
        ()
        if resource is None
        else ((resource.RLIMIT_AS, memory.vms + stacks), (resource.RLIMIT_DATA, getattr(memory, "data", 0)))
    )
    for which, used in limits:
        soft = resource.getrlimit(which)[0]
        if soft != resource.RLIM_INFINITY:
            available = min(available, max(soft - used, 0))
    cgroup = _cgroup_headroom()
    if cgroup is not None:
        available = min(available, cgroup)
    return available


def _cgroup_headroom(root: str = "/sys/fs/cgroup", proc: str = "/proc/self/cgroup") -> int | None:
    """The cgroup's memory limit less its usage (cgroup v2, else v1), or None
    where there is no limit. The process's own cgroup is read first, then
    the root of the hierarchy, which is the container's own in a container."""
    paths = [""]
    try:
        with open(proc, encoding="ascii") as f:
            for line in f:
                _, controllers, where = line.rstrip("\n").split(":", 2)
                if controllers in ("", "memory") and where not in ("", "/"):
                    paths.insert(0, where)
    except (OSError, ValueError):
        pass
    for limit_file, usage_file in (
        ("{}{}/memory.max", "{}{}/memory.current"),
        ("{}/memory{}/memory.limit_in_bytes", "{}/memory{}/memory.usage_in_bytes"),
    ):
        for where in paths:
            try:
                with open(limit_file.format(root, where), encoding="ascii") as f:
                    limit = f.read().strip()
                with open(usage_file.format(root, where), encoding="ascii") as f:
                    usage = int(f.read())
            except (OSError, ValueError):
                continue
            # "max" (v2) or a huge number (v1): no limit
            if limit == "max" or int(limit) >= 2**62:
                return None
            return max(int(limit) - usage, 0)
    return None
