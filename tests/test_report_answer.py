"""A report opens with the answer (the headline and the thesis's verdicts, on one screen), lists
each machine once, says what each headline ratio divides by, holds no empty field and no "None",
and report.html holds report.md's sections (issue 40)."""

import html
import re

import numpy as np
from test_report import machine, ramp, rec, thesis, write

from raybench.bench import report
from raybench.bench.report import answer

H2_MD = re.compile(r"^## (.*)$", re.M)
H2_HTML = re.compile(r"<h2[^>]*>(.*?)</h2>", re.S)
H3_MD = re.compile(r"^### (.*)$", re.M)
H3_HTML = re.compile(r"<h3[^>]*>(.*?)</h3>", re.S)


def _text(s: str) -> str:
    return html.unescape(re.sub(r"<[^>]+>", "", s)).strip()


def _records(rng):
    run = {"settings": {"suites": ["thesis"], "devices": ["cpu", "cuda"], "builds": [], "adapter": None, "seed": 0}}
    records = thesis(rng) + [ramp(rng, device="cuda"), ramp(rng, device="cpu")]
    # the headline's points: brute force with the fast kernel at 800x600
    for device, scale in (("cpu", 1.0), ("cuda", 0.02)):
        for n in (100, 500, 1000):
            records.append(rec("thesis", device, n, scale * n / 10, options={"kernel": "fast", "accel": "none"}))
    for r in records:
        r["run"] = {**r["run"], **run, "git_commit": "abc123def456"}
    return records


def _report(tmp_path, rng):
    path = write(tmp_path / "run.jsonl", _records(rng))
    md = report.write_report([path], tmp_path / "rep").read_text()
    return md, (tmp_path / "rep" / "report.html").read_text()


def test_the_report_opens_with_the_answer_on_one_screen(tmp_path, rng):
    md, page = _report(tmp_path, rng)
    sections = H2_MD.findall(md)
    assert sections[:3] == ["The answer", "Machines", "How the verdicts are decided"]
    opening = md.split("## The answer\n", 1)[1].split("\n## ", 1)[0]
    # the headline and every claim's verdict, in at most one screen of lines
    assert "| alpha | Synthetic CPU, 4 cores |" in opening and "| alpha | Synthetic GPU |" in opening
    assert all(f"| {n} |" in opening for n in range(1, 7))
    assert len(opening.splitlines()) <= 30
    assert _text(H2_HTML.findall(page)[0]) == "The answer"


def test_a_headline_ratio_names_what_it_divides_by(tmp_path, rng):
    md, page = _report(tmp_path, rng)
    header = next(line for line in md.splitlines() if line.startswith("| machine | device | million rays/s"))
    assert "÷ Synthetic CPU, 4 cores (alpha)" in header
    assert "÷ Synthetic CPU, 4 cores (alpha)" in page
    assert "Claim 1 below divides the CPU's median frame time by the GPU's" in md
    claim1 = next(line for line in md.splitlines() if line.startswith("| 1 | The GPU is faster"))
    assert "(CPU median frame time / GPU's, point by point)" in claim1


def test_a_compile_time_from_the_cache_is_not_quoted_to_the_microsecond():
    from raybench.bench.report.numbers import fmt_compile_s

    assert fmt_compile_s(0.0000227) == "< 0.001 (from the cache)"
    assert fmt_compile_s(1.234) == "1.23" and fmt_compile_s(None) == "–"


def test_html_and_markdown_hold_the_same_sections(tmp_path, rng):
    md, page = _report(tmp_path, rng)
    assert [_text(h) for h in H2_HTML.findall(page)] == [html.unescape(h) for h in H2_MD.findall(md)]
    in_page = {_text(h) for h in H3_HTML.findall(page)}
    assert {html.unescape(h) for h in H3_MD.findall(md)} <= in_page
    # test 7 and the fits with their R², which the page once lacked
    for needle in ("Test 7", "R²"):
        assert needle in md and needle in page
    fits = [line for line in md.splitlines() if line.startswith("| 800x600 |") and "R²" not in line]
    assert fits and all(_text(cell) in _text(page) for cell in fits[0].strip("|").split("|")[:3])


def test_each_machine_once_with_no_empty_field(tmp_path, rng):
    md, page = _report(tmp_path, rng)
    machines = md.split("## Machines\n", 1)[1].split("\n## ", 1)[0]
    assert machines.count("**alpha**") == 1
    assert re.findall(r"<tr><td>alpha</td>", page.split('id="machines"', 1)[1].split("</table>", 1)[0]) == [
        "<tr><td>alpha</td>"
    ]
    shown = re.sub(r"<script.*?</script>", "", page, flags=re.S)  # plotly.js has its own None
    assert "None" not in md and "None" not in _text(shown)
    assert "builds" not in machines and "adapter" not in machines  # empty, so left out
    assert "settings: suites thesis, devices cpu+cuda, seed 0" in machines
    assert not re.search(r"(\| *\|)|(, ,)|(: ;)", md)


def test_a_reference_made_from_these_records_is_listed_once(rng):
    records = _records(rng)
    rows = answer.headline_rows(records, [dict(r) for r in records])
    assert [(r["label"], r["device"], r["reference"]) for r in rows] == [
        ("alpha", "cpu", False),
        ("alpha", "cuda", False),
    ]
    other = [{**r, "run": {**r["run"], "label": "ref", "machine": machine()}} for r in records]
    assert len(answer.headline_rows(records, other)) == 4


def test_a_reference_without_a_headline_says_why():
    from raybench import references
    from raybench.bench import headline

    assert not headline.unscored(references.load())  # every reference machine has a headline
    # the 2-core EPYC as it shipped before its fast-kernel run: its simple kernel's records alone
    shipped = [
        r
        for r in references.load()
        if r["run"]["label"] != "epyc-2c-cpu-only" or (r["options"] or {}).get("kernel", "simple") != "fast"
    ]
    (line,) = headline.unscored(shipped)
    assert line.startswith("epyc-2c-cpu-only: no headline v1: its thesis records are the simple kernel's")
    assert any(line in x for x in headline.summary(_records(np.random.default_rng(0)), shipped))


def test_the_raw_data_is_linked_from_the_report(tmp_path, rng):
    from urllib.parse import unquote

    folder = tmp_path / "my runs [1]"
    folder.mkdir()
    path = write(folder / "run #1.jsonl", _records(rng))
    out = tmp_path / "rep"
    md = report.write_report([path], out).read_text()
    sources = md.split("## Sources\n", 1)[1].split("\n## ", 1)[0]
    (link,) = re.findall(r"^- \[.*\]\(([^)\s]+)\)$", sources, re.M)
    assert (out / unquote(link)).resolve() == path.resolve()
    page = (out / "report.html").read_text()
    assert f'href="{link}"' in page


def test_a_slope_flat_within_a_microsecond_reads_as_flat():
    from raybench.bench.report.numbers import fmt_slope

    # -2.49e-7 ms a sphere over 100..1000 spheres: 0.22 µs in all (the h200 report's 1280x800 GPU)
    assert fmt_slope(-0.000000249, [100, 1000]) == "flat (< 1 µs over the series)"
    assert fmt_slope(0.0285, [100, 1000]) == "0.0285" and fmt_slope(None, [1, 2]) == "–"


def test_bench_ends_with_the_verdicts(rng):
    from raybench import references
    from raybench.bench.report.verdicts import verdicts

    records = _records(rng)
    lines = answer.verdict_lines(records, [])
    assert lines[0].startswith("the thesis's claims")
    column = report.group(records)["alpha, simple kernel"]
    judged = [v for v in verdicts(column) if v["verdict"] != "not measured"]
    block = lines[lines.index("  alpha, simple kernel:") + 1 :]
    for v in judged:
        assert f"    {v['number']}. {v['claim']}: {v['verdict']}; {v['measured']}" in block
    # a CPU-only machine: the claims that need a GPU, with each reference GPU, named as another machine's
    cpu_only = [r for r in records if r["device"] == "cpu"]
    lines = answer.verdict_lines(cpu_only, references.load())
    assert any("with the NVIDIA H200 of h200 (another machine" in line for line in lines)
    assert any(line.startswith("    not measured in this run: claims 1, 3") for line in lines)
