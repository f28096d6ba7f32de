"""A results file is data: whatever text it carries (a CPU model, a label, a
setting, an adapter's name) shows in report.md as written and adds no HTML,
link, image or table cell."""

import re

import pytest

from raybench.bench import report
from raybench.bench.results import ResultsWriter

HOSTILE = "<img src=x onerror=alert(1)>![x](http://e/x.png)"
# What escape() makes of it: every "<", ">", "[" and "]" a character reference.
INERT = "&lt;img src=x onerror=alert(1)&gt;!&#91;x&#93;(http://e/x.png)"


def test_escape_makes_the_hostile_string_inert():
    assert report.escape(HOSTILE) == INERT
    assert report.escape("a|b `c` *d* \\e\nf") == "a&#124;b &#96;c&#96; &#42;d&#42; &#92;e f"
    # already escaped text is not unescaped: the "&" itself is escaped
    assert report.escape("&lt;img&gt;") == "&amp;lt;img&amp;gt;"
    # what real machines write is left as it was
    for plain in ("Intel(R) Xeon(R) Processor", "llvmpipe (LLVM 15.0.6, 256 bits)", "duration_s 2.0, seed 0"):
        assert report.escape(plain) == plain


def records(text: str) -> list[dict]:
    """A thesis run and a CPU tuning run whose every text field is `text`."""
    machine = {
        "os": text,
        "cpu": {"model": text, "physical_cores": 4, "logical_cpus": 8, "simd": text, "fp32_gflops": 200.0},
        "gpus": [{"name": text, "multiprocessors": 40, "driver": text, "fp32_gflops": 10000.0}],
        "versions": {"raybench": text, "numba": text},
    }
    # labels alone are plain names: the results schema refuses any other (tests/test_hardening.py)
    run = {"id": text, "date": "2024-05-01T12:00:00+00:00", "label": "hostile", "git_commit": text, "machine": machine}
    run["settings"] = {"suites": [text], "note": text}

    def rec(suite, device, spheres, median, **extra):
        return {
            "suite": suite,
            "device": device,
            "width": 800,
            "height": 600,
            "spheres": spheres,
            "test": 1,
            "options": {},
            "frame_ms": {"median": median, "p5": 0.9 * median, "p95": 1.1 * median},
            "kernel_ms": None,
            "run": run,
            **extra,
        }

    out = [rec("thesis", d, n, n * (1.0 if d == "cpu" else 0.01)) for d in ("cpu", "cuda") for n in (100, 200, 300)]
    out += [rec("tuning", "cpu", 1000, t, options={"threads": k, "label": "hostile"}) for k, t in ((1, 9.0), (8, 2.0))]
    return out


def test_hostile_text_in_a_results_file_comes_out_inert(tmp_path):
    path = tmp_path / "r.jsonl"
    with ResultsWriter(path) as w:
        for r in records(HOSTILE):
            w.write(r)
    text = report.write_report([path], tmp_path / "rep").read_text(encoding="utf-8")
    assert INERT in text  # it is shown, as written
    assert "<img" not in text and "](http" not in text and "![x]" not in text
    # the report's own images are its only ones, each a PNG it wrote
    images = re.findall(r"!\[[^\]]*\]\(([^)]*)\)", text)
    assert images and all(re.fullmatch(r"[A-Za-z0-9._-]+\.png", name) for name in images), images
    assert all((tmp_path / "rep" / name).is_file() for name in images)
    # no "|" from the file splits a table row: every row of the claims table has its columns
    header = next(line for line in text.splitlines() if line.startswith("| # |"))
    for line in text.splitlines():
        if re.match(r"\| [1-6] \|", line):
            assert line.count(" | ") == header.count(" | "), line


@pytest.mark.filterwarnings("error:Glyph")  # a chart drawing ESC or BEL (matplotlib has no glyph for them)
def test_control_characters_are_shown_not_kept(tmp_path):
    """ESC and NUL from a results file were written raw into report.md (a
    terminal that cats it obeys them); now as their escapes, in report.md
    and report.html alike."""
    assert report.escape("a\x1b[2Jb\x00c\x07") == "a&#92;x1b&#91;2Jb&#92;x00c&#92;x07"
    path = tmp_path / "r.jsonl"
    with ResultsWriter(path) as w:
        for r in records("Evil\x1b]0;owned\x07 CPU\x00"):
            w.write(r)
    md = report.write_report([path], tmp_path / "rep")
    for page in (md, md.with_suffix(".html")):
        text = page.read_text(encoding="utf-8")
        # (report.html inlines plotly.js, whose own source holds control characters: the record's are looked for)
        assert "\x1b]0;owned" not in text and "owned\x07" not in text and "CPU\x00" not in text, page.name
        assert "x1b" in text and "owned" in text, page.name  # shown, as written
    assert "Evil&#92;x1b&#93;0;owned&#92;x07 CPU&#92;x00" in md.read_text(encoding="utf-8")
