"""raybench compare: two results files, point by point, with a verdict on each change."""

from __future__ import annotations

from pathlib import Path

import click

from ..errors import RaybenchError


@click.command(name="compare")
@click.argument("old", type=click.Path(path_type=Path))
@click.argument("new", type=click.Path(path_type=Path))
@click.option(
    "--noise",
    "noise_pct",
    type=float,
    default=5.0,
    show_default=True,
    help="changes smaller than this many percent are within noise, however sure",
)
@click.option(
    "--fail-slower",
    "fail_pct",
    type=float,
    help="exit with status 1 if a point is judged slower by this many percent or more (a CI gate)",
)
def compare_cmd(old, new, noise_pct, fail_pct):
    """Compare two results files (JSON Lines from `raybench bench`) point by
    point: the change in each point's median frame time, its 95% confidence
    interval (a bootstrap over the frames), and a verdict: faster, slower, or
    within noise. Points measured in only one run, or differently, are listed
    as not comparable. The runs may come from two machines or two versions.
    With --fail-slower, runs with no point in common are an error (exit 2):
    a gate that compared nothing has passed nothing."""
    import math

    from ..bench import compare, results
    from .out import Progress, echo

    if fail_pct is not None and (math.isnan(fail_pct) or not 0 <= fail_pct <= 1000):
        raise RaybenchError(f"--fail-slower: must be from 0 to 1000 percent, got {fail_pct:g}")
    progress = Progress("compare: points")
    try:
        runs = results.read(old, compact=True), results.read(new, compact=True)
        comparison = compare.compare(*runs, noise_pct, progress=progress)
    finally:
        progress.end()
    if fail_pct is not None and not comparison.changes:
        raise RaybenchError(
            f"--fail-slower {fail_pct:g}: {old} and {new} have no point in common, so nothing was compared "
            "(run compare without --fail-slower to see why)"
        )
    for line in compare.lines(comparison, str(old), str(new)):
        echo(line)
    if fail_pct is not None:
        slower = comparison.slower(fail_pct)
        if slower:
            click.echo(
                f"raybench: compare: {len(slower)} point{'s' if len(slower) != 1 else ''} slower by "
                f"{fail_pct:g}% or more (--fail-slower {fail_pct:g})",
                err=True,
            )
            click.get_current_context().exit(1)
