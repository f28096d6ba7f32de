"""The report as Markdown: report.md beside its PNG charts.

Text taken from a results file (labels, CPU and GPU names, settings, notes)
enters the Markdown only through escape(): a results file is data, and must
not put HTML, links or images into the report.

This module lays the page out; markdown_blocks has what it is written with,
thesis_sections and beyond_sections the sections of each suite."""

from __future__ import annotations

import os
import re
from pathlib import Path
from urllib.parse import quote

from ... import references as raybench_references
from ...errors import RaybenchError
from ...files import folder_atomic, write_atomic
from .. import headline
from ..suites import REGISTRY
from . import answer, html
from .beyond_sections import _section_dynamic, _section_multi_gpu, _section_parts, _section_scaling, _section_secondary
from .markdown_blocks import _table, _Writer, escape
from .meshes_section import _section_meshes
from .records import load
from .scenes_section import _section_scenes
from .thesis_sections import _section_constant, _section_speedup, _section_test7, _section_thesis, _section_tuning
from .verdicts import CLAIMS, RULES, THESIS_CPU, THESIS_GPU, verdicts, with_reference_gpus


def _slug(label: str, taken: set) -> str:
    slug = re.sub(r"[^A-Za-z0-9._-]+", "-", label).strip("-.") or "machine"
    base, i = slug, 2
    while slug in taken:
        slug, i = f"{base}-{i}", i + 1
    taken.add(slug)
    return slug


def _claims_table(machines: dict[str, list[dict]]) -> tuple[str, dict[str, list[dict]]]:
    judged = {label: verdicts(records) for label, records in machines.items()}
    header = ["#", "the thesis's claim", "what the thesis measured"] + [escape(label) for label in machines]
    rows = []
    for i, (claim, thesis) in enumerate(CLAIMS):
        row = [i + 1, claim, thesis]
        for label in machines:
            v = judged[label][i]
            row.append(f"**{v['verdict']}**: {escape(v['measured'])}")  # names settings from the results
        rows.append(row)
    return _table(header, rows), judged


def _section_references(w: _Writer, machines: dict[str, list[dict]], references: list[dict]) -> None:
    """The headline beside the reference machines, and the claims that need a GPU judged,
    where a machine here has none, with each reference GPU: always named as another machine."""
    w("## Beside the reference machines", "")
    w(
        "raybench ships results measured on other machines (benchmarks/make_references.py makes them from the "
        "records under benchmarks/results/). They are **not** this run's machines: each is named, with the "
        "commit it was measured at; their headlines are in the table at the top. "
        "`raybench report --no-references` leaves them out.",
        "",
    )
    for pair in with_reference_gpus(machines, references):
        label, ref, gpu_name, judged = pair["label"], pair["ref"], pair["gpu"], pair["judged"]
        w(
            f"### {escape(label)}: the claims that need a GPU, with the {escape(gpu_name)} of {escape(ref)} "
            "(another machine)",
            "",
            f"This machine has no GPU in these results; below, its CPU is set against {escape(ref)}'s GPU, "
            f"measured elsewhere (commit {escape(pair['commit'])}, {escape(pair['date'])}). Claims 4 and 6 are "
            "that GPU's alone.",
            "",
        )
        rows = [[v["number"], v["claim"], f"**{v['verdict']}**: {escape(v['measured'])}"] for v in judged]
        w(_table(["#", "the thesis's claim", f"this CPU with {escape(ref)}'s GPU"], rows), "")


def write_report(paths: list, out_dir, references: bool = True) -> Path:
    """Read the results files, write out_dir/report.md and its PNG plots, and
    report.html beside them (out_dir is created if needed), and return the
    path of report.md.
    references: place the machines against raybench's reference machines
    (raybench.references), and judge the claims a missing GPU leaves open with theirs."""
    out_dir = Path(out_dir)
    # Checked before any work: the folder is made aside and renamed into place, which
    # "." (or "", which Path reads as "."), ".." and "/" name no folder to do to.
    if out_dir.name in ("", ".", ".."):
        raise RaybenchError(
            f"{str(out_dir) or repr('')}: name a new or empty folder for the report (it is made whole, then renamed "
            "into place), e.g. raybench-report"
        )
    if out_dir.exists() and not out_dir.is_dir():
        raise RaybenchError(f"{out_dir}: is a file, not a folder for the report")
    sources: list = []
    machines, notes = load(paths, sources)
    # the suites with a section of their own (suites.Suite.section) are no part of the thesis's claims, nor are parts
    beyond: dict[str, dict[str, list[dict]]] = {r: {} for s in REGISTRY if s.section for r in s.writes}
    beyond["parts"] = {}
    for records in machines.values():
        for r in records:
            if r["suite"] in beyond:
                beyond[r["suite"]].setdefault(r["run"]["label"], []).append(r)
    machines = {k: v for k, v in ((k, [r for r in v if r["suite"] not in beyond]) for k, v in machines.items()) if v}
    # built aside and renamed into place: never a half-made report under out_dir's name
    with folder_atomic(out_dir, _ours) as staged:
        w = _Writer(staged)
        w.final_dir = out_dir
        _write(sources, machines, notes, beyond, w, raybench_references.load() if references else None)
    return out_dir / "report.md"


def _link(source, report_dir: Path) -> str:
    """A results file as a link from the report's folder: its path relative to the report,
    percent-encoded, so that no character of a file's name can end the link or add markup."""
    relative = os.path.relpath(Path(source).resolve(), Path(report_dir).resolve())
    return quote(Path(relative).as_posix(), safe="/")


def _ours(entry: Path) -> bool:
    """What an earlier report left in its folder, which a new one may replace."""
    return (
        entry.is_file()
        and not entry.is_symlink()
        and (entry.name in ("report.md", "report.html") or entry.suffix in (".png", ".jpg"))
    )


# The parts beyond the thesis, in the report's order: the suite whose records a part reads, its heading,
# and the section that writes one run of it. A section of its own for a new suite is one line here.
_BEYOND = (
    ("scaling", "scaling with a BVH", _section_scaling),
    ("secondary", "secondary rays", _section_secondary),
    ("multi-gpu", "across GPUs and workers", _section_multi_gpu),
    ("dynamic", "spheres that move", _section_dynamic),
    ("scenes", "real scenes", _section_scenes),
    ("meshes", "triangles", _section_meshes),
    ("parts", "parts timed apart", _section_parts),
)


def _write(sources, machines, notes, beyond, w: _Writer, references: list[dict] | None) -> None:
    thesis_labels = [records[0]["run"]["label"] for records in machines.values() if records]
    labels = list(dict.fromkeys(thesis_labels + [label for suite, _, _ in _BEYOND for label in beyond[suite]]))
    on = ", ".join(labels) if len(labels) <= 3 else f"{len(labels)} machines and runs (listed under Machines)"
    w(f"# raybench: the 2010 GPU ray-tracing thesis, measured again on {escape(on)}", "")
    w(
        "Persson and Udd (2010) rendered spheres with one brute-force ray tracer (one primary ray per pixel, "
        f"tested against every sphere) on an {THESIS_CPU} and on a {THESIS_GPU} with a DirectX 11 compute "
        "shader. raybench runs the same algorithm, written once, on each device here, repeats the thesis's "
        "tests, and checks each of its claims. The answer comes first; the details follow, grouped by "
        "machine and suite, and the results files they come from are listed at the end.",
        "",
    )
    mine = [r for records in machines.values() for r in records]
    table = answer.headline_rows(mine, references)
    w("## The answer", "")
    if table:
        w(f"The {escape(headline.DEFINITION)} (raybench.bench.headline):", "")
        w(answer.headline_table(table), "")
        w(
            *[f"- {escape(line)}" for line in headline.unscored(references or [])],
            "",
            answer.RATIO_NOTE,
            "",
            answer.INTERVAL_NOTE,
            "",
        )
    w("### The thesis's claims", "")
    claims, judged = _claims_table(machines)
    w(claims, "")
    w("## Machines", "")
    measured = [(column, records) for column, records in machines.items()]
    measured += [(f"{label}, {suite}", records) for suite, found in beyond.items() for label, records in found.items()]
    w(*answer.machines_markdown(measured))
    w("## How the verdicts are decided", "")
    w(*[f"- {rule}" for rule in RULES], "")
    if references:
        _section_references(w, machines, references)
    opening = len(w.lines)
    taken: set = set()
    for label, records in machines.items():
        slug = _slug(label, taken)
        w(f"## {escape(label)}", "")
        for section in (_section_thesis, _section_speedup, _section_test7, _section_tuning, _section_constant):
            section(w, label, slug, records)
    for suite, title, section in _BEYOND:
        if beyond[suite]:
            w(f"## Beyond the thesis: {title}", "")
        for label, records in beyond[suite].items():
            slug = _slug(f"{label}-{suite}", taken)
            if section is _section_secondary:  # it describes the machine of a run with no thesis section
                section(w, label, slug, records, describe=label not in thesis_labels)
            elif section is _section_meshes:  # Embree's figures of the same label (parts) beside its cpu's
                section(w, label, slug, records + beyond["parts"].get(label, []))
            else:
                section(w, label, slug, records)
    w("## Sources", "")
    # a file's name is the user's text like any other: escaped, never a code span it could end
    w(*[f"- [{escape(p)}]({_link(p, w.final_dir)})" for p in sources], "")
    if notes:
        w("## Notes", "")
        w(*[f"- {escape(n)}" for n in notes], "")
    write_atomic(w.out_dir / "report.md", "\n".join(w.lines).encode("utf-8"))
    details = w.lines[opening:]
    page = html.render(sources, machines, references, table, measured, details, w.shown)
    write_atomic(w.out_dir / "report.html", page.encode("utf-8"))
