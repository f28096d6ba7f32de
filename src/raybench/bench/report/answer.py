"""The report's opening, the same in report.md and report.html: the answer first (the headline
and the thesis's verdicts, on one screen), then each machine once.

A headline ratio always says what it divides by. Two ratios appear in a report and they differ
by design (docs/thesis.md#two-ratios-two-questions): the headline table's divides one device's
headline (brute force, 800x600, three scenes, geometric mean of rays a second) by this run's
CPU's; claim 1's divides the CPU's median frame time by the GPU's, point by point over tests
1-6, and gives their least, median and most."""

from __future__ import annotations

from .. import headline
from .markdown_blocks import _table, escape
from .numbers import fmt_num, fmt_x
from .records import fmt_opt
from .series import machine_of


def ratio_header(table: list[dict]) -> str:
    """The headline table's ratio column, naming what it divides by."""
    base = next((r for r in table if not r["reference"] and r["device"] == "cpu"), None)
    return f"÷ {base['name']} ({base['label']})" if base else "÷ this run's CPU"


RATIO_NOTE = (
    "Each ratio in this table is a device's headline divided by this run's CPU's headline (the column's "
    "header names it). Claim 1 below divides the CPU's median frame time by the GPU's at each point of "
    "tests 1-6, up to 1680x1050 and 1000 spheres, where a GPU has more work to fill it: its median is "
    "larger than the headline's ratio, and both are right."
)
INTERVAL_NOTE = (
    "The 95% interval: the wider of the spread between the run's passes over the headline's points (the "
    "first, and the repeats later in the run) and the bootstrap over their frames; records without repeats "
    "carry the latter only. A load that held through the whole run moves every pass, and another run can "
    "fall outside it (docs/thesis.md, the headline's interval)."
)


def headline_rows(records: list[dict], references: list[dict] | None) -> list[dict]:
    """headline.rows, each with its 95% interval where the records kept their frames."""
    table = headline.rows(records, references or [])
    # a reference made from these very records (a report over benchmarks/results/h200) is one machine, listed once
    own = {(r["label"], r["device"], r["value"]) for r in table if not r["reference"]}
    table = [r for r in table if not (r["reference"] and (r["label"], r["device"], r["value"]) in own)]
    for r in table:
        source = (references or []) if r["reference"] else records
        r["interval"] = headline.interval([x for x in source if x["run"]["label"] == r["label"]], r["device"])
    return table


def fmt_interval(span) -> str:
    return f"{fmt_num(span[0])} to {fmt_num(span[1])}" if span else "frames not kept"


def headline_table(table: list[dict]) -> str:
    rows = [
        [
            escape(r["label"]) + (" (reference: another machine)" if r["reference"] else ""),
            escape(r["name"]),
            fmt_num(r["value"]),
            fmt_interval(r["interval"]),
            fmt_x(r["cpu_ratio"]) if r["cpu_ratio"] else "no CPU in this run",
            escape(r["commit"] or "not recorded"),
        ]
        for r in table
    ]
    header = [
        "machine",
        "device",
        "million rays/s",
        "95% interval, within its run",
        escape(ratio_header(table)),
        "commit",
    ]
    return _table(header, rows)


def machines_by_label(measured: list[tuple[str, list[dict]]]) -> dict[str, list[tuple[str, list[dict]]]]:
    """Each machine (a run label) once, with what it was measured as: (name, records) pairs, a
    report column ("h200, BVH") or a suite beyond the thesis ("h200, scaling")."""
    out: dict[str, list] = {}
    for name, records in measured:
        if records:
            out.setdefault(records[0]["run"]["label"], []).append((name, records))
    return out


def settings_text(settings: dict) -> str:
    """A run's settings, every one that holds a value: an empty list or None is left out."""
    shown = [
        f"{k} {'+'.join(map(str, v)) if isinstance(v, list) else fmt_opt(v)}"
        for k, v in settings.items()
        if v is not None and v != [] and v != ""
    ]
    return ", ".join(shown)


def machine_rows(measured: list[tuple[str, list[dict]]]) -> list[dict]:
    """One row a machine: its processors, the columns it was measured as, and its runs, each
    with its commit as it was recorded (with -dirty only where the tree had changes)."""
    rows = []
    for label, named in machines_by_label(measured).items():
        records = [r for _, rs in named for r in rs]
        m = machine_of(records)
        cpu = m.get("cpu") or {}
        runs: dict = {}
        for r in records:
            runs.setdefault(r["run"].get("id"), r["run"])
        rows.append(
            {
                "label": label,
                "as": [name.removeprefix(f"{label}, ") for name, _ in named],
                "cpu": cpu.get("model") or "CPU not described",
                "cores": cpu.get("physical_cores") or "not recorded",
                "gpu": ", ".join(str(g.get("name")) for g in m.get("gpus") or []) or "no CUDA GPU",
                "os": m.get("os") or "not recorded",
                "runs": [
                    {
                        "id": run.get("id") or "not recorded",
                        "date": run.get("date") or "not recorded",
                        "commit": run.get("git_commit") or "not recorded",
                        "settings": settings_text(run.get("settings") or {}) or "not recorded",
                    }
                    for run in runs.values()
                ],
            }
        )
    return rows


def machines_markdown(measured: list[tuple[str, list[dict]]]) -> list[str]:
    lines = []
    for m in machine_rows(measured):
        lines.append(
            f"**{escape(m['label'])}** (measured as: {escape(', '.join(m['as']))}): CPU {escape(m['cpu'])} "
            f"({escape(m['cores'])} cores); GPU {escape(m['gpu'])}; {escape(m['os'])}."
        )
        for run in m["runs"]:
            lines.append(
                f"- run {escape(run['id'])}: {escape(run['date'])}, commit {escape(run['commit'])}; "
                f"settings: {escape(run['settings'])}"
            )
        lines.append("")
    return lines


def _judged_lines(judged: list[dict]) -> list[str]:
    """Each claim judged, one line; those not measured gathered in one line at the end."""
    from .verdicts import NOT_MEASURED

    out = [
        f"    {v['number']}. {v['claim']}: {v['verdict']}; {v['measured']}"
        for v in judged
        if v["verdict"] != NOT_MEASURED
    ]
    missing = [str(v["number"]) for v in judged if v["verdict"] == NOT_MEASURED]
    if missing:
        out.append(f"    not measured in this run: claim{'s' if len(missing) > 1 else ''} {', '.join(missing)}")
    return out


def verdict_lines(records: list[dict], references: list[dict] | None) -> list[str]:
    """The thesis's verdicts as `raybench bench` prints them at its end, one line a claim and
    report column; on a machine without a GPU, the claims that need one also with each reference
    GPU, named as another machine's. The report has the rules and the reasons."""
    from .records import group
    from .verdicts import verdicts, with_reference_gpus

    columns = {c: rs for c, rs in group(records).items() if any(r["suite"] in ("thesis", "test7") for r in rs)}
    if not columns:
        return []
    out = ["the thesis's claims (the report has the rules and the reasons):"]
    for column, rs in columns.items():
        out += [f"  {column}:", *_judged_lines(verdicts(rs))]
    for pair in with_reference_gpus(columns, references or []):
        gpu = f"the {pair['gpu']} of {pair['ref']}"
        out += [
            f"  {pair['label']} with {gpu} (another machine, commit {pair['commit']}):",
            *_judged_lines(pair["judged"]),
        ]
    return out
