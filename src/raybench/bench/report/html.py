"""report.html: the report as one self-contained page that works offline:
Jinja2 templates (templates/), the charts drawn by plotly.js, inlined, with
values on hover and machines toggled on and off from the legend; the claims
table; the headline beside the reference machines, and the claims a missing
GPU leaves open judged with theirs, which a checkbox hides.

Text from a results file reaches the page only through Jinja2's autoescaping
(in the HTML, its control characters written as escapes) or as JSON inside a <script type="application/json"> element
with <, > and & written as \\u escapes (the charts' data), and plotly draws
it as text: it is shown as written and runs nothing.
"""

from __future__ import annotations

import html as html_text
import json
import re

import jinja2

from ...errors import controls_shown
from .. import headline, pictures
from . import answer
from .series import speedups, thesis_series
from .verdicts import CLAIMS, RULES, verdicts, with_reference_gpus

_ENV = jinja2.Environment(
    loader=jinja2.PackageLoader("raybench.bench.report", "templates"),
    autoescape=True,
    undefined=jinja2.StrictUndefined,
    trim_blocks=True,
    lstrip_blocks=True,
    # a record's control characters shown as their escapes (Markup, the page's own HTML, is left whole)
    finalize=lambda value: controls_shown(value) if type(value) is str else value,
)


def _script_json(value) -> str:
    """value as JSON that no text in it can end the <script> element holding it."""
    text = json.dumps(value, separators=(",", ":"), allow_nan=False)
    return text.replace("<", "\\u003c").replace(">", "\\u003e").replace("&", "\\u0026")


def _plain(text) -> str:
    """Text for plotly, which reads a few HTML tags in it: entities instead, shown as written."""
    return html_text.escape(str(text), quote=False)


def _figure(traces: list[dict], title: str, x: str, y: str, log: bool = False) -> dict:
    axis = {"type": "log"} if log else {}
    return {
        "data": traces,
        "layout": {
            "title": {"text": _plain(title)},
            "xaxis": {"title": {"text": x}},
            "yaxis": {"title": {"text": y}, **axis},
            "hovermode": "closest",
            "legend": {"title": {"text": "click to toggle"}},
            "margin": {"t": 50, "r": 20, "b": 150},
        },
    }


def _charts(machines: dict[str, list[dict]], table: list[dict]) -> list[dict]:
    charts = []
    traces = []
    for column, records in machines.items():
        for s in thesis_series(records):
            traces.append(
                {
                    "type": "scatter",
                    "mode": "lines+markers",
                    "name": _plain(f"{column}: {s['device']} {s['width']}x{s['height']}"),
                    "x": s["spheres"],
                    "y": s["median"],
                    "hovertemplate": "%{x} spheres: %{y:.4g} ms<extra>%{fullData.name}</extra>",
                }
            )
    if traces:
        charts.append(
            {"id": "chart-thesis", "figure": _figure(traces, "Tests 1-6: median frame time", "spheres", "ms", True)}
        )
    traces = []
    for column, records in machines.items():
        sp = speedups(records)
        for size in dict.fromkeys((p["width"], p["height"]) for p in sp):
            pts = [p for p in sp if (p["width"], p["height"]) == size]
            traces.append(
                {
                    "type": "scatter",
                    "mode": "lines+markers",
                    "name": _plain(f"{column}: {size[0]}x{size[1]}"),
                    "x": [p["spheres"] for p in pts],
                    "y": [p["speedup"] for p in pts],
                    "hovertemplate": "%{x} spheres: %{y:.3g}x<extra>%{fullData.name}</extra>",
                }
            )
    if traces:
        charts.append(
            {"id": "chart-speedup", "figure": _figure(traces, "GPU speedup over the CPU", "spheres", "CPU / GPU")}
        )
    if table:
        traces = []
        for reference in (False, True):
            rows = [r for r in table if r["reference"] == reference]
            for label in dict.fromkeys(r["label"] for r in rows):
                mine = [r for r in rows if r["label"] == label]
                name = f"{label} (reference: another machine)" if reference else label
                traces.append(
                    {
                        "type": "bar",
                        "name": _plain(name),
                        "x": [_plain(r["name"]) for r in mine],
                        "y": [r["value"] for r in mine],
                        "meta": "reference" if reference else "this run",
                        "hovertemplate": "%{x}: %{y:.4g} million rays/s<extra>%{fullData.name}</extra>",
                    }
                )
        charts.append(
            {
                "id": "chart-headline",
                "figure": _figure(
                    traces,
                    f"headline v{headline.VERSION}: brute force, thesis scenes at 800x600",
                    "device",
                    "million rays/s",
                    True,
                ),  # fmt: skip
            }
        )
    return charts


def _details(lines: list[str], shown: dict[str, bytes] | None = None) -> str:
    """report.md's details (from its first machine's section on) as HTML: the same sections, so
    the page and report.md never differ in what they hold. Their text from a results file went
    through escape() (character references: no tag, link or image); a chart, drawn as a PNG
    beside report.md, is linked rather than shown, so the page fetches nothing; a traced frame
    (shown: its JPEG by file name) is shown, inlined as a data: URI."""
    import markdown

    shown = shown or {}

    def line_of(line: str) -> str:
        found = _CHART.match(line)
        if found is None:
            return line
        alt, name = found.groups()
        if name in shown:
            return f"![{alt}]({pictures.uri(shown[name])})"
        return f"[chart: {alt}]({name})"

    text = "\n".join(line_of(line) for line in lines)
    return markdown.markdown(text, extensions=["tables"], output_format="html")


_CHART = re.compile(r"^!\[([^\]]*)\]\(([^)\s]+)\)$")


def render(
    sources, machines: dict[str, list[dict]], references, table, measured, details: list[str], shown=None
) -> str:
    """The page's text: the answer (headline and verdicts), the machines, the rules and the
    references, in the template; then report.md's details, rendered."""
    from plotly.offline import get_plotlyjs

    judged = {column: verdicts(records) for column, records in machines.items()}
    points = [
        {
            "column": column,
            "device": r["device"],
            "size": f"{r['width']}x{r['height']}",
            "spheres": r["spheres"],
            "median_ms": f"{r['frame_ms']['median']:.4g}",
        }
        for column, records in machines.items()
        for r in records
        if r["suite"] == "thesis"
    ]
    return _ENV.get_template("report.html.j2").render(
        claims=CLAIMS,
        rules=RULES,
        judged=judged,
        columns=list(machines),
        machines=answer.machine_rows(measured),
        headline=headline,
        table=table,
        ratio_header=answer.ratio_header(table),
        ratio_note=answer.RATIO_NOTE,
        interval_note=answer.INTERVAL_NOTE,
        unscored=headline.unscored(references or []),
        fmt_interval=answer.fmt_interval,
        references=references is not None,
        with_references=with_reference_gpus(machines, references) if references else [],
        charts=[{"id": c["id"], "json": _script_json(c["figure"])} for c in _charts(machines, table)],
        points=points,
        details=_details(details, shown),
        plotly_js=get_plotlyjs(),
    )
