"""The benchmark on every machine of a Dask cluster (`raybench bench
--scheduler`): one worker of each machine runs bench.runner's loop, all
machines at once, and each machine's records come back whole.
"""

from __future__ import annotations

import os
import re
from collections.abc import Callable

from ..cluster.tasks import task_lock
from ..errors import RaybenchError, one_line
from . import suites


def machine_key(worker: dict) -> str:
    """The machine a worker runs on, from its entry in the scheduler's
    worker info: its host's address."""
    return worker["host"]


def bench_workers(client) -> dict[str, str]:
    """One worker per machine of the cluster: {worker address: machine key},
    the first worker of each machine by address. A machine with several
    workers (one per GPU, say) runs the benchmark once: two runs at once on
    one machine would share its cores, memory bandwidth and GPUs, and each
    would measure the other."""
    from distributed import TimeoutError as DaskTimeout

    try:
        workers = client.scheduler_info(n_workers=-1)["workers"]
    except (OSError, DaskTimeout) as exc:
        raise RaybenchError(f"cluster: its scheduler did not answer ({one_line(exc)})") from None
    machines: dict[str, str] = {}
    for address, info in sorted(workers.items()):
        machines.setdefault(machine_key(info), address)
    if not machines:
        raise RaybenchError("cluster: it has no workers")
    return {address: key for key, address in machines.items()}


def _slug(text: str) -> str:
    return re.sub(r"[^A-Za-z0-9._-]+", "-", text).strip("-.")[:40] or "machine"


def bench_labels(hosts: dict[str, str], label: str | None) -> dict[str, str]:
    """Each worker's run label: its host name (after label and a dash, if
    given), made unique with -2, -3, ... where two machines share a name."""
    out, seen = {}, {}
    for address, host in hosts.items():
        name = _slug(host) if label is None else f"{label}-{_slug(host)}"
        seen[name] = seen.get(name, 0) + 1
        out[address] = name if seen[name] == 1 else f"{name}-{seen[name]}"
    return out


def _bench_check(devices: list[str], adapter: str | None) -> str:
    """On a worker: its host name, once each device asked for is found there."""
    import socket

    from .. import backends

    for d in devices:
        backends.resolve(d, adapter if d == "wgpu" else None)
    return socket.gethostname()


def _bench_run(settings: dict, label: str, argv: list[str]) -> list[dict]:
    """A task: the bench's points measured on this worker's machine, by the
    same loop as on the command line (bench.runner.run); its records."""
    import socket

    from . import runner

    settings = {**settings, "host": socket.gethostname(), "pid": os.getpid()}
    points, info = runner.plan(settings, label, argv)
    records = runner.Records()
    with task_lock:  # no tile or frame task of this worker at the same time
        runner.run(points, records, info, settings["duration_s"], settings["seed"], progress=False)
    return records.records


def bench(
    client,
    settings: dict,
    label: str | None = None,
    on_records: Callable[[list[dict]], None] | None = None,
    argv: list[str] | None = None,
) -> int:
    """The benchmark (settings as bench.runner.plan takes them) on one
    worker of each machine of the cluster (bench_workers()), all machines at
    once, each with its own machine's description and devices (settings'
    devices, checked on every machine first; none given: each machine's
    own). A machine's records come back whole when its run ends, and go to
    on_records(records) as they arrive. Each run's settings say which worker
    ("worker"), host and process ran it. Returns how many records came; a
    machine whose run failed is an error naming its worker, raised once the
    others have finished."""
    import sys

    from distributed import TimeoutError as DaskTimeout
    from distributed import as_completed

    for name in settings["suites"]:
        if suites.suite(name).one_machine:
            raise RaybenchError(
                f"--suite {name}: {suites.suite(name).one_machine}; run it on one machine, without --scheduler"
            )
    chosen = bench_workers(client)
    try:
        answers = client.run(
            _bench_check, list(settings["devices"]), settings.get("adapter"), workers=list(chosen), on_error="return"
        )
    except (OSError, DaskTimeout) as exc:
        raise RaybenchError(f"cluster: its workers did not answer ({one_line(exc)})") from None
    for worker, answer in sorted(answers.items()):
        if isinstance(answer, BaseException):
            raise RaybenchError(f"worker {worker}: {one_line(answer)}")
    labels = bench_labels({address: answers[address] for address in chosen}, label)
    argv = sys.argv[1:] if argv is None else list(argv)
    tasks = {
        client.submit(
            _bench_run,
            {**settings, "worker": address},
            labels[address],
            argv,
            workers=[address],
            allow_other_workers=False,
            pure=False,
        ): address
        for address in chosen
    }
    count, failed = 0, []
    try:
        for task in as_completed(tasks):
            try:
                records = task.result()
            except Exception as exc:  # noqa: BLE001 - any machine's failure is named once the others end
                failed.append(f"worker {tasks[task]}: {one_line(exc)}")
                continue
            count += len(records)
            if on_records is not None:
                on_records(records)
    finally:
        # Ctrl-C or an error: what arrived is kept; what is queued is dropped.
        client.cancel(list(tasks))
    if failed:
        more = f" (and {len(failed) - 1} other machines failed)" if len(failed) > 1 else ""
        raise RaybenchError(failed[0] + more)
    return count
