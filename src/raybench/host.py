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


def host_available_bytes() -> int:
    """What this process may still allocate: the free memory, or less where a
    ulimit (address space, data) or the cgroup's memory limit leaves less.
    Beyond it an allocation ends in a MemoryError or the OOM killer."""
    available = psutil.virtual_memory().available
    memory = psutil.Process().memory_info()
    limits = (
        ()
        if resource is None
        else ((resource.RLIMIT_AS, memory.vms), (resource.RLIMIT_DATA, getattr(memory, "data", 0)))
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
