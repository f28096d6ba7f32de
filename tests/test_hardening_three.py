"""Issue 39's items that have no test file of their own: a report's folder
checked before the work, parts records without samples compared. Each test
failed before its fix."""

import json

import pytest
from test_compare import point

from raybench.bench import compare, results
from raybench.cli import run


def part(median: float, **extra) -> dict:
    return {
        "format": results.FORMAT,
        "version": results.VERSION,
        "suite": "parts",
        "quantity": "bvh-build",
        "device": "cpu",
        "time_ms": {"median": median, "p5": 1.0, "p95": 4.0},
        "run": point([1.0], 1)["run"],
        **extra,
    }


@pytest.mark.parametrize("out", [".", "", "..", "/"])
def test_report_refuses_a_folder_it_cannot_replace_before_any_work(tmp_path, monkeypatch, capsys, out):
    """report -o . and -o '' raised ValueError after all the work: the folder is made
    aside and renamed into place, and "." names none to rename."""
    monkeypatch.chdir(tmp_path)
    (tmp_path / "r.jsonl").write_text(json.dumps(part(2.0)) + "\n")
    assert run(["report", "r.jsonl", "-o", out]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "name a new or empty folder for the report" in err, err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["r.jsonl"]


def test_parts_without_samples_are_compared_without_a_traceback(tmp_path, capsys):
    """A parts record may leave out its sample count: compare raised TypeError (int(None))."""
    old, new = tmp_path / "old.jsonl", tmp_path / "new.jsonl"
    old.write_text(json.dumps(part(2.0)) + "\n")
    new.write_text(json.dumps(part(3.0)) + "\n")
    (c,) = compare.compare(results.read(old), results.read(new)).changes
    assert c.verdict == compare.TOO_FEW and c.ratio == 1.5
    assert run(["compare", str(old), str(new)]) == 0
    assert "parts bvh-build cpu" in capsys.readouterr().out
