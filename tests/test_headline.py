"""The headline number and the reference results shipped in the package: the
shipped records are exactly what benchmarks/make_references.py makes from the
committed records, small, and whole (machines, commits); the headline is the
geometric mean it is defined as (worked out here from the records), and only
the points of its definition count; a run without a GPU is placed against
the references' GPUs, always named as other machines, in the terminal and
the report."""

import gzip
import importlib.util
import json
import math
from pathlib import Path

import numpy as np
import pytest
from test_report import machine, rec, write

from raybench import references
from raybench.bench import headline, report
from raybench.bench.report import answer
from raybench.cli import run

ROOT = Path(__file__).resolve().parent.parent
SHIPPED = ROOT / "src" / "raybench" / "references" / "references.jsonl.gz"


def make_references():
    spec = importlib.util.spec_from_file_location("make_references", ROOT / "benchmarks" / "make_references.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_the_shipped_references_are_what_the_script_makes_from_the_committed_records():
    script = make_references()
    assert script.OUT == SHIPPED
    # the records byte for byte (the gzip around them differs by Python and zlib version)
    assert gzip.decompress(SHIPPED.read_bytes()) == gzip.decompress(script.make()), "run benchmarks/make_references.py"
    assert SHIPPED.stat().st_size < 300 * 1024
    for name, _ in (f for files in script.SOURCES.values() for f in files):
        assert (ROOT / "benchmarks" / "results" / name).is_file(), name


def test_each_reference_machine_is_described_with_its_commit():
    by = references.machines()
    assert set(by) == {"h200", "h100", "epyc-2c-cpu-only"}
    assert len(gzip.decompress(SHIPPED.read_bytes()).splitlines()) == sum(map(len, by.values()))
    for label, records in by.items():
        thesis = [r for r in records if r["suite"] == "thesis"]
        assert thesis, label
        assert all(r["run"]["git_commit"] for r in thesis), label
        assert all(r["run"]["machine"]["cpu"]["model"] for r in records)
    assert by["h200"][0]["run"]["machine"]["gpus"][0]["name"] == "NVIDIA H200"
    assert not by["epyc-2c-cpu-only"][0]["run"]["machine"]["gpus"]
    # the references' headlines, from the definition: every machine measured the fast kernel
    scores = headline.scores(references.load())
    assert set(scores) == {"h200", "h100", "epyc-2c-cpu-only"} and set(scores["epyc-2c-cpu-only"]) == {"cpu"}
    assert all(s["cuda"] > 10 * s["cpu"] for label, s in scores.items() if label != "epyc-2c-cpu-only")


EPYC = ROOT / "benchmarks" / "results" / "epyc-2c-cpu-only" / "headline" / "main-job-20261203-112326.jsonl"


def _epyc_by_hand() -> tuple[float, str]:
    """The 2-core EPYC's headline worked out from its committed file with json alone (not
    raybench's reader or headline.score): 800x600 / median frame time at the three sphere
    counts, brute force by the fast kernel, geometric mean; and the commit it was measured at."""
    rates, commits = {}, set()
    for line in EPYC.read_text().splitlines():
        r = json.loads(line)
        key = (r["suite"], r["width"], r["height"], r["options"].get("accel"), r["options"].get("kernel"))
        if key == ("thesis", 800, 600, "none", "fast") and r["spheres"] in (100, 500, 1000):
            rates[r["spheres"]] = 800 * 600 / (r["frame_ms"]["median"] / 1e3) / 1e6
            commits.add(r["run"]["git_commit"])
    assert sorted(rates) == [100, 500, 1000] and len(commits) == 1
    return (rates[100] * rates[500] * rates[1000]) ** (1 / 3), commits.pop()


def test_the_2_core_epyc_reference_is_in_the_headline_table(rng):
    """The EPYC's older thesis records are the simple kernel's (measured before the fast one
    existed) and come first under its label: its row must take the fast run's figure and commit."""
    expected, commit = _epyc_by_hand()
    mine = points(rng)
    (row,) = [r for r in headline.rows(mine, references.load()) if r["label"] == "epyc-2c-cpu-only"]
    assert row["reference"] and row["device"] == "cpu" and row["name"] == "AMD EPYC, 2 cores"
    assert math.isclose(row["value"], expected, rel_tol=1e-12)
    assert row["commit"] == commit != "ca4274070b05"  # not the simple-kernel run's, listed first
    assert math.isclose(row["cpu_ratio"], expected / headline.score(mine, "cpu"), rel_tol=1e-12)
    lines = headline.summary(mine, references.load())
    assert any(x.startswith("  epyc-2c-cpu-only ") and "AMD EPYC, 2 cores" in x for x in lines)
    assert not headline.unscored(references.load())
    # the report's table holds it too, with its interval over its kept frames
    (shown,) = [r for r in answer.headline_rows(mine, references.load()) if r["label"] == "epyc-2c-cpu-only"]
    low, high = shown["interval"]
    assert low <= expected <= high


def test_the_epyc_row_goes_when_its_records_lose_the_kernel():
    """The kernel taken off the EPYC's records: they read as the simple kernel's (the only one
    before the fast kernel), the row goes and the reason is said. (Its accel is checked above:
    the figure by hand reads only records that say accel none.)"""
    shipped = references.load()
    for r in shipped:
        if r["run"]["label"] == "epyc-2c-cpu-only":
            r["options"].pop("kernel", None)
    assert "epyc-2c-cpu-only" not in {r["label"] for r in headline.rows([], shipped)}
    (line,) = headline.unscored(shipped)
    assert line.startswith("epyc-2c-cpu-only: no headline v1: its thesis records are the simple kernel's")


def points(rng, device="cpu", kernel="fast", spheres=headline.SPHERES, size=headline.SIZE, **kw):
    out = []
    for n in spheres:
        r = rec("thesis", device, n, float(rng.uniform(1, 100)), size=size, options={"accel": "none", "kernel": kernel})
        r["run"].update(kw)
        out.append(r)
    return out


def test_the_headline_is_the_geometric_mean_of_its_points_only(rng):
    mine = points(rng)
    rates = [800 * 600 / (r["frame_ms"]["median"] / 1e3) / 1e6 for r in mine]
    expected = float(np.prod(rates) ** (1 / 3))
    # other points measured beside them change nothing
    others = points(rng, spheres=(200, 300)) + points(rng, kernel="simple") + points(rng, size=(1280, 800))
    bvh = [{**r, "options": {"accel": "bvh"}} for r in points(rng)]
    assert math.isclose(headline.score(mine + others + bvh, "cpu"), expected, rel_tol=1e-12)
    assert headline.score(mine[:2], "cpu") is None  # a point missing: no headline
    assert headline.score(points(rng, kernel="simple"), "cpu") is None  # not the definition's kernel
    assert headline.score(points(rng, settings={"seed": 3}), "cpu") is None  # other scenes
    assert headline.score(points(rng, device="wgpu", kernel="simple"), "wgpu") is not None  # wgpu's only kernel


def test_a_cpu_only_run_is_placed_against_the_reference_gpus(rng):
    mine = points(rng)
    lines = headline.summary(mine, references.load())
    assert lines[0].startswith("headline v1: ")
    assert lines[1].startswith("  this machine ") and "Synthetic CPU" in lines[1]
    assert "reference machines (measured elsewhere" in lines[2]
    h200 = next(line for line in lines if "NVIDIA H200" in line and line.startswith("  h200"))
    ratio = headline.scores(references.load())["h200"]["cuda"] / headline.score(mine, "cpu")
    assert f"({ratio:.3g}x this CPU)" in h200
    assert lines[-1].startswith("  no GPU measured here:") and "other machines' GPUs" in lines[-1]
    with_gpu = headline.summary(mine + points(rng, device="cuda"), references.load())
    assert "x this machine's CPU" in with_gpu[2] and not any("no GPU measured here" in x for x in with_gpu)
    (alone,) = headline.summary(points(rng, spheres=(100,)), [])
    assert alone.endswith("not measured in this run (it needs the thesis suite)")


@pytest.mark.parametrize("flag", [[], ["--no-references"]])
def test_the_report_judges_the_gpu_claims_with_the_references_and_says_so(tmp_path, rng, flag):
    mine = points(rng, size=(800, 600)) + points(rng, size=(1280, 800))
    for r in mine:
        r["run"]["machine"] = {**machine(), "gpus": []}
    path = write(tmp_path / "cpu-only.jsonl", mine)
    assert run(["report", str(path), "-o", str(tmp_path / "rep"), *flag]) == 0
    text = (tmp_path / "rep" / "report.md").read_text()
    if flag:
        assert "reference" not in text.lower().replace("references.md", "")
        return
    assert "## Beside the reference machines" in text
    assert "| h200 (reference: another machine) | NVIDIA H200 |" in text
    heading = "### alpha, fast kernel: the claims that need a GPU, with the NVIDIA H200 of h200 (another machine)"
    assert heading in text
    section = text.split(heading, 1)[1].split("###", 1)[0]
    assert "| 1 | The GPU is faster than the CPU" in section and "**holds**" in section
    # the claims table of this machine alone still says what it measured: no GPU here
    claims = text.split("## The thesis's claims", 1)[1].split("## Beside", 1)[0]
    assert "not measured" in claims and "H200" not in claims
    # the page says the same, section for section
    page = (tmp_path / "rep" / "report.html").read_text()
    assert heading.removeprefix("### ") in page
    part = page.split(heading.removeprefix("### "), 1)[1].split("</table>", 1)[0]
    assert "<td>1</td><td>The GPU is faster than the CPU" in part and '<span class="holds">holds</span>' in part
    report.write_report([path], tmp_path / "rep2", references=False)
    assert "Beside the reference machines" not in (tmp_path / "rep2" / "report.md").read_text()
