"""The Markdown that every part of report.md is written with: escape(),
through which alone text from a results file enters the report; tables; a
machine's description; and the _Writer that collects the report's lines and
writes each chart as it is drawn."""

from __future__ import annotations

import json
from pathlib import Path

from ...errors import controls_shown
from ...files import write_atomic
from .records import fmt_opt
from .series import machine_of

# Character references, not backslashes: a reference is never Markdown syntax,
# whatever stands before it, and _cell's escaping of "|" cannot undo it.
_INERT = str.maketrans(
    {
        "&": "&amp;",
        "<": "&lt;",  # HTML tags and autolinks
        ">": "&gt;",
        "[": "&#91;",  # links and images
        "]": "&#93;",
        "\\": "&#92;",  # backslash escapes
        "`": "&#96;",  # code spans
        "*": "&#42;",  # emphasis
        "|": "&#124;",  # table cells
        "\n": " ",
        "\r": " ",
    }
)


def escape(text) -> str:
    """Text from a results file (a label, a CPU model, a setting, a note) as
    inert Markdown: it shows as written and adds no HTML, link, image, code,
    emphasis or table cell, and no control character (ESC, NUL: shown as
    \\x1b, \\x00). Every such text enters the report through here."""
    return controls_shown(str(text)).translate(_INERT)


def _cell(text) -> str:
    """A table cell of the report's own text (record text is escape()d first)."""
    return str(text).replace("|", "\\|").replace("\n", " ")


def _table(header: list[str], rows: list[list]) -> str:
    lines = ["| " + " | ".join(_cell(h) for h in header) + " |", "|" + "---|" * len(header)]
    lines += ["| " + " | ".join(_cell(c) for c in row) + " |" for row in rows]
    return "\n".join(lines)


def _adapter_name(records: list[dict]) -> str:
    """The wgpu adapter of these records, e.g. "llvmpipe (...) (Vulkan, CPU)": a CPU driver must not pass for a GPU."""
    names = sorted(
        {
            f"{a.get('name')} ({a.get('backend')}, {a.get('type')})"
            for r in records
            if r["device"] == "wgpu" and isinstance(a := r.get("adapter"), dict)
        }
    )
    return ", ".join(names) or "unknown adapter"


def write_verdict(w, question: str, judge, rule: str, records: list[dict], points: list[dict]) -> dict:
    """A suite's verdict as the report writes every one: the question and judge(records)'s answer,
    wgpu's answer for information where wgpu measured (judge(records, "wgpu")), then the rule;
    returns judge(records), whose points the section may tabulate."""
    judged = judge(records)
    w(f"**{question}** **{judged['verdict']}**: {escape(judged['measured'])}", "")
    if any(p["device"] == "wgpu" for p in points):
        info = judge(records, "wgpu")
        w(f"wgpu on {escape(_adapter_name(records))}, for information: {escape(info['measured'])}", "")
    w(f"The rule: {rule}", "")
    return judged


def _machine_lines(label: str, records: list[dict]) -> list[str]:
    # every value below is the results file's text: escaped where it is read
    m = machine_of(records)
    cpu = {k: escape(v) for k, v in (m.get("cpu") or {}).items()}
    versions = {k: escape(v) if v else v for k, v in (m.get("versions") or {}).items()}
    gpus = [{k: escape(v) if v else v for k, v in g.items()} for g in m.get("gpus") or []]
    gpu = (
        (
            f"{gpus[0].get('name')} ({gpus[0].get('multiprocessors', '?')} multiprocessors, "
            f"{gpus[0].get('memory_gib', '?')} GiB, driver {gpus[0].get('driver') or '?'})"
        )
        if gpus
        else "no CUDA GPU"
    )
    lines = [
        f"**{escape(label)}**: CPU {cpu.get('model', '?')} ({cpu.get('physical_cores', '?')} cores, "
        f"{cpu.get('logical_cpus', '?')} threads); GPU {gpu}; {escape(m.get('os', ''))}; "
        f"raybench {versions.get('raybench') or '?'}, numba {versions.get('numba') or '?'}, "
        f"numba-cuda {versions.get('numba-cuda') or '?'}."
    ]
    runs = {}
    for r in records:
        runs.setdefault(r["run"].get("id"), (r["run"], []))[1].append(r)
    for run, rs in runs.values():
        settings = run.get("settings") or {}
        shown = escape(", ".join(f"{k} {fmt_opt(v)}" for k, v in settings.items()))
        lines.append(
            f"- run {escape(run.get('id', '?'))}: {escape(run.get('date', '?'))}, "
            f"git {escape(run.get('git_commit') or 'unknown')}, {len(rs)} points; settings: {shown or 'none recorded'}"
        )
    machines = {json.dumps(r["run"]["machine"].get("cpu"), sort_keys=True) for r in records}
    if len(machines) > 1:
        lines.append(
            "- note: the runs under this label describe different CPUs; the first run's machine is used "
            "for the theoretical rates"
        )
    return lines


class _Writer:
    """Collects the report's lines and writes each plot as soon as it is drawn."""

    def __init__(self, out_dir: Path):
        self.out_dir = out_dir
        self.final_dir = out_dir  # where the report will be once renamed into place: links are relative to it
        self.lines: list[str] = []
        self.pngs: list[Path] = []
        self.shown: dict[str, bytes] = {}  # pictures (JPEG) the HTML page shows inline, by file name

    def __call__(self, *lines: str) -> None:
        self.lines.extend(lines)

    def image(self, name: str, data: bytes, alt: str) -> None:
        path = self.out_dir / name
        write_atomic(path, data)
        self.pngs.append(path)
        self(f"![{escape(alt)}]({name})", "")  # alt names the machine: the results file's text

    def picture(self, name: str, jpeg: bytes, alt: str) -> None:
        """A traced frame (JPEG): a file beside report.md, as a chart is, and shown inline in report.html."""
        self.image(name, jpeg, alt)
        self.shown[name] = jpeg
