"""raybench report: result files into a Markdown report with plots and verdicts."""

from __future__ import annotations

from pathlib import Path

import click

from ..errors import one_line
from .options import path_option


@click.command(name="report")
@click.argument("results", nargs=-1, required=True, type=click.Path(path_type=Path))
@path_option(
    "-o",
    "--out",
    "out_dir",
    default=Path("raybench-report"),
    show_default=True,
    help_text="folder for report.md and its plots",
)
@click.option(
    "--references/--no-references",
    default=True,
    show_default=True,
    help="place the machines beside raybench's reference machines (measured elsewhere, and named so)",
)
def report_cmd(results, out_dir, references):
    """Turn result files (JSON Lines from `raybench bench`) into a Markdown report
    with plots and a verdict on each of the thesis's claims. Several files (two
    machines, say) go side by side in one report. A folder stands for every
    .jsonl file under it; those that are not raybench results are skipped,
    with a warning each. The report folder is made whole, then put in place."""
    import warnings

    from ..bench import report

    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        path = report.write_report(list(results), out_dir, references)
    for w in caught:
        click.echo(f"raybench: warning: {one_line(w.message)}", err=True)
    click.echo(f"report: {path} (and {path.with_suffix('.html')}, one page that works offline)")
