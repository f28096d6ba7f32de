"""raybench bench: the thesis's experiments on this machine, or on every machine
of a Dask cluster, then a report."""

from __future__ import annotations

import os
import sys
from pathlib import Path

import click

from ..backends.options import ACCELS, KERNELS
from ..bench.suites import CAPPED, REGISTRY
from ..errors import RaybenchError, Terminated, device_failure, one_line
from .options import (
    adapter_option,
    build_option,
    choice_option,
    connect_timeout_option,
    open_cluster,
    path_option,
    scheduler_option,
    scheduler_security,
    tls_options,
)


@click.command()
@click.option(
    "--suite",
    "suites",
    multiple=True,
    default=("thesis",),
    show_default=True,
    help=f"{', '.join(s.help for s in REGISTRY)}, or all (every one; a point predicted past a frame-time cap is "
    f"skipped in {', '.join(CAPPED)}: brute force's, and every mesh's); repeat for several",
)
@click.option(
    "--device", "devices", multiple=True, help="cpu, cuda or wgpu; repeat for several (default: every device present)"
)
@adapter_option()
@click.option(
    "--duration", type=float, help="seconds of timed frames per point, after warm-up (default 10; 0.5 with --quick)"
)
@choice_option(
    "kernel",
    KERNELS,
    "kernels for the thesis and tuning suites; repeat for both (default fast; "
    "constant-vs-runtime always uses simple, the only one with a compile-time count, "
    "and so does secondary's brute force, the only one Whitted shading has)",
    multiple=True,
)
@choice_option(
    "accel",
    ACCELS,
    "bvh, none (brute force), or both repeated (the default): the thesis, tuning, scaling and "
    "secondary suites measure each; constant-vs-runtime and test 7 are brute force only",
    multiple=True,
)
@build_option(multiple=True)
@click.option("--quick", is_flag=True, help="a reduced set of points: about a minute on a 2-core laptop")
@path_option(
    "--out",
    "out_dir",
    help_text="folder for the results and the report (default: raybench-results/<machine>, or /cluster with "
    "--scheduler)",
)
@click.option(
    "--label",
    help="short machine name used in the report (default: from the GPU or CPU name; with --scheduler, each "
    "machine's host name, after this label and a dash if given)",
)
@click.option("--seed", type=int, default=0, show_default=True, help="seed of the random scenes")
@click.option("--no-report", is_flag=True, help="only write the results; skip the report")
@scheduler_option(
    "run the suites on every machine of the running Dask cluster whose scheduler is at this address, "
    "once a machine (on one of its workers), with its own devices and description; each machine's "
    "records arrive when its run ends, into one results file and one report, the machines side by side"
)
@tls_options()
@connect_timeout_option()
def bench(
    suites,
    devices,
    adapter,
    kernels,
    accels,
    builds,
    duration,
    quick,
    out_dir,
    label,
    seed,
    no_report,
    scheduler,
    tls_ca,
    tls_cert,
    tls_key,
    connect_timeout,
):
    """Run the thesis's experiments on this machine, then write a report;
    with --scheduler, on every machine of a Dask cluster.

    Results go to a JSON Lines file, one record per point as soon as it is
    measured (across a cluster: each machine's as its run ends): an
    interrupted run (Ctrl-C) keeps every record written.
    """
    import datetime

    from ..bench import runner
    from ..bench import suites as suites_mod
    from ..bench.load import Load, warning
    from ..bench.results import MAX_NUMBER, ResultsWriter, check_label, check_settings

    chosen = suites_mod.SUITES if "all" in suites else tuple(dict.fromkeys(suites))
    for s in chosen:
        if s not in suites_mod.SUITES:
            raise RaybenchError(f"--suite: unknown suite {s!r}; choose from {', '.join(suites_mod.SUITES)} or all")
    scheduler = scheduler or os.environ.get("RAYBENCH_SCHEDULER") or None
    security = scheduler_security(scheduler, tls_ca, tls_cert, tls_key)
    if scheduler is not None and "all" in suites:
        # all, across a cluster: every suite that runs on each machine (a one_machine suite starts its own workers)
        chosen = tuple(s for s in chosen if not suites_mod.suite(s).one_machine)
    if duration is None:
        duration = 0.5 if quick else 10.0
    if not 0.05 <= duration <= 3600:
        raise RaybenchError(f"--duration: must be from 0.05 to 3600 seconds, got {duration:g}")
    # the rules the results' reader applies, checked before the work: a run never
    # writes records that its own report refuses (a seed past 1e15, a label "..")
    if not 0 <= seed <= MAX_NUMBER:
        raise RaybenchError(f"--seed: must be a whole number from 0 to {MAX_NUMBER:g}, got {seed}")
    if label is not None:
        check_label(label)
    if out_dir is not None and out_dir.exists() and not out_dir.is_dir():
        raise RaybenchError(f"--out {out_dir}: is a file, not a folder")
    settings = {
        "suites": list(chosen),
        "devices": list(dict.fromkeys(devices)),  # none: each machine's own, as plan() finds them
        "kernels": list(dict.fromkeys(kernels)) or ["fast"],
        "accels": list(dict.fromkeys(accels)) or list(ACCELS),
        "builds": list(dict.fromkeys(builds)),
        "duration_s": duration,
        "quick": quick,
        "seed": seed,
        "adapter": adapter,
    }
    check_settings(settings)
    for note in idle_options(settings, bool(kernels)):
        click.echo(note)
    stamp = datetime.datetime.now().strftime("%Y%m%d-%H%M%S")
    load = Load()
    if scheduler is not None:
        from ..bench import machines as on_machines

        out_dir = out_dir or Path("raybench-results") / (label or "cluster")
        results_path = out_dir / f"results-{stamp}.jsonl"
        with open_cluster(None, "auto", scheduler, connect_timeout, security) as running:
            machines = on_machines.bench_workers(running.client)
            click.echo(
                f"{', '.join(settings['suites'])} on {len(machines)} machine{'s' if len(machines) != 1 else ''} "
                f"of {scheduler}, {duration:g} s a point; results: {results_path}"
            )
            with ResultsWriter(results_path) as writer:
                _bench_into(
                    writer,
                    results_path,
                    lambda: on_machines.bench(
                        running.client, settings, label, lambda rs: [writer.write(r) for r in rs]
                    ),
                )
    else:
        points, info = runner.plan(settings, label)
        label = info["label"]
        out_dir = out_dir or Path("raybench-results") / label
        if out_dir.exists() and not out_dir.is_dir():
            raise RaybenchError(f"--out {out_dir}: is a file, not a folder")
        results_path = out_dir / f"results-{stamp}.jsonl"
        devices = info["settings"]["devices"]
        click.echo(f"{len(points)} points on {', '.join(devices)}, {duration:g} s each; results: {results_path}")
        # rich's bar on a terminal; piped (a file, a CI log), a plain line a point on stdout
        bar = sys.stderr.isatty() and sys.stdout.isatty()
        with ResultsWriter(results_path) as writer:
            _bench_into(
                writer,
                results_path,
                lambda: runner.run(
                    points, writer, info, duration, seed, progress=bar, lines=None if bar else click.echo
                ),
            )
    click.echo(f"wrote {writer.count} results to {results_path}")
    if not no_report:
        from ..bench import report

        path = report.write_report([results_path], out_dir / f"report-{stamp}")
        click.echo(f"report: {path} (and {path.with_suffix('.html')}, one page that works offline)")
    if writer.count:
        from .. import references
        from ..bench import headline
        from ..bench.report.answer import verdict_lines
        from ..bench.results import read

        records, shipped = read(results_path), references.load()
        for line in verdict_lines(records, shipped) + headline.summary(records, shipped):
            click.echo(line)
    if scheduler is None and (loaded := warning(load.others())):
        click.echo(loaded)


def idle_options(settings: dict, kernels_given: bool) -> list[str]:
    """The options asked for that will change nothing in this run, each said in one line."""
    notes = []
    if kernels_given and "none" not in settings["accels"]:
        notes.append("note: --kernel has no effect: it picks a brute-force kernel, and --accel bvh times the BVH only")
    if kernels_given and settings["devices"] == ["wgpu"] and settings["kernels"] != ["simple"]:
        notes.append("note: --kernel fast has no effect on wgpu: its one brute-force kernel is the simple one")
    if settings["builds"] and "bvh" not in settings["accels"]:
        notes.append("note: --build has no effect: it says where the BVH is built, and --accel none measures no BVH")
    return notes


def _bench_into(writer, results_path, measure) -> None:
    """bench's measure() into writer: a failure or Ctrl-C says how many of
    its records are kept, all of them on disk already."""
    try:
        measure()
    except Exception as exc:
        failure = device_failure(exc) or (one_line(exc) if isinstance(exc, RaybenchError) else None)
        if failure is None:
            raise
        kept = (
            f"the {writer.count} finished points are in {results_path}"
            if writer.count
            else "no point had finished; no results were written"
        )
        raise RaybenchError(f"{failure}; {kept}") from None
    except KeyboardInterrupt as exc:
        what = "terminated (SIGTERM)" if isinstance(exc, Terminated) else "interrupted"
        click.echo(
            f"raybench: {what}; the {writer.count} finished points are in {results_path} "
            f"(report them with: raybench report {results_path})"
            if writer.count
            else f"raybench: {what} before the first point finished; no results were written",
            err=True,
        )
        raise SystemExit(143 if isinstance(exc, Terminated) else 130) from None
