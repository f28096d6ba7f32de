"""The published JSON Schema says what results.check_record does: committed
records and fresh ones pass both, and every hostile value refused by the
reader is refused by the schema too (the two are built from the same
checkers; this holds them to it). docs/results-schema.json is up to date."""

import copy
import json
from pathlib import Path

import jsonschema
import pytest
from test_compare import frames, point
from test_report import set_at

from raybench.bench import results
from raybench.cli import run
from raybench.errors import RaybenchError

ROOT = Path(__file__).resolve().parent.parent
LIVE = [p for p in sorted((ROOT / "benchmarks" / "results").rglob("*.jsonl")) if "archive" not in p.parts]
VALIDATOR = jsonschema.Draft202012Validator(results.schema())


def full(record):
    return {"format": results.FORMAT, "version": results.VERSION, **record}


def test_the_schema_is_valid_json_schema_and_published():
    jsonschema.Draft202012Validator.check_schema(results.schema())
    assert json.loads((ROOT / "docs" / "results-schema.json").read_text()) == results.schema()


def test_the_command_prints_it(capsys):
    assert run(["schema"]) == 0
    assert json.loads(capsys.readouterr().out) == results.schema()


def test_committed_records_pass_the_schema():
    """The first and last three records of every committed file (the reader checks every one)."""
    checked = 0
    for path in LIVE:
        lines = [line for line in path.read_text().splitlines() if line.strip()]
        for line in lines[:3] + lines[-3:]:
            errors = list(VALIDATOR.iter_errors(json.loads(line)))
            assert not errors, f"{path}: {errors[0].message[:200]}"
            checked += 1
    assert checked > 200


HOSTILE = {
    "workers as text": set_at(["options", "workers"], "two"),
    "workers 0": set_at(["options", "workers"], 0),
    "job as a list": set_at(["options", "job"], ["frame"]),
    "job as a number": set_at(["options", "job"], 1),
    "build as a number": set_at(["options", "build"], 3),
    "label as a list": set_at(["options", "label"], ["a"]),
    "threads as text": set_at(["options", "threads"], "many"),
    "tree width 3": set_at(["options", "tree_width"], 3),
    "a mesh no suite makes": set_at(["options", "mesh"], "teapot"),
    "triangles as a fraction": set_at(["options", "triangles"], 2.5),
    "block of one side": set_at(["options", "block"], [16]),
    "a denormal time": set_at(["frame_ms", "median"], 5e-324),
    "a denormal rate": set_at(["rays_per_s"], 5e-324),
    "a sample of 0 ms": set_at(["samples_ms", 0], 0),
    "label ..": set_at(["run", "label"], ".."),
    "label with a space": set_at(["run", "label"], "a b"),
    "test 9": set_at(["test"], 9),
    "a count as text": set_at(["frames"], "many"),
    "a huge seed in settings": set_at(["run", "settings"], {"seed": 18446744073709551616}),
}


@pytest.mark.parametrize("name", HOSTILE)
def test_what_the_reader_refuses_the_schema_refuses(rng, name):
    record = full(point(frames(rng, 10.0, 20), 100, options={"workers": 2, "job": "frame"}))
    assert not list(VALIDATOR.iter_errors(record))
    results.check_record(record, "record")
    bad = copy.deepcopy(record)
    HOSTILE[name](bad)
    with pytest.raises(RaybenchError):
        results.check_record(bad, "record")
    assert list(VALIDATOR.iter_errors(bad)), name


# --- one definition, two readings: every counter-example refused by both ---------------------

# What each leaf of a record is replaced by: the values a hand edit or another
# writer puts where a number, a text or a flag belongs.
COUNTER = [True, False, None, 1.5, 800.0, -1, 0, "800", "a\nb", "\x1b[2J", [], {}, 1e300]
# The reader's rules that JSON Schema cannot state (schema()'s docstring lists them): where the
# schema takes a value the reader refuses, the reader's message must name one of these.
BEYOND_SCHEMA = ("in order", "between min and max", "within frame_ms's", "of median", "as long as")


def leaves(value, prefix=()):
    if isinstance(value, dict):
        for key, item in value.items():
            yield from leaves(item, (*prefix, key))
    elif isinstance(value, list) and value:
        for i, item in enumerate(value[:2]):
            yield from leaves(item, (*prefix, i))
    else:
        yield prefix


def test_the_reader_and_the_schema_agree_on_every_counter_example(rng):
    """Every leaf of a full record (its options, summary, samples, run and
    machine) set to each of COUNTER: the reader and the published schema take
    or refuse it alike, but for the rules the schema cannot state. The reader
    had taken 800.0 for a whole number through its cache of runs, and any
    value under an option name it did not know."""
    record = full(point(frames(rng, 10.0, 20), 100, options={"workers": 2, "job": "frame", "newer": "text"}))
    record["run"]["settings"] = {"seed": 3, "quick": True}
    paths = list(leaves(record))
    assert len(paths) > 25
    disagreed = []
    for path in paths:
        for value in COUNTER:
            bad = copy.deepcopy(record)
            set_at(list(path), value)(bad)
            schema_takes = not list(VALIDATOR.iter_errors(bad))
            try:
                results.parse_records(json.dumps(bad) + "\n", "r.jsonl")
                reader_takes, why = True, ""
            except RaybenchError as exc:
                reader_takes, why = False, str(exc)
            # JSON Schema's integer takes 800.0 (a number with no fraction); the reader, as written, does not
            beyond = any(rule in why for rule in BEYOND_SCHEMA) or (value == 800.0 and "a whole number" in why)
            if schema_takes != reader_takes and not (schema_takes and beyond):
                disagreed.append((path, value, schema_takes, why))
    assert not disagreed, disagreed[:5]


def lines_of(*records) -> str:
    return "".join(json.dumps(full(r)) + "\n" for r in records)


def test_a_run_seen_before_is_compared_as_written(rng):
    """4.0 == 4 and true == 1: the reader's cache of runs already checked took
    a run whose cores read 4.0 (or a setting true for 1) as the run before it."""
    first = point(frames(rng, 10.0, 20), 100)
    first["run"]["machine"] = {"cpu": {"physical_cores": 4}, "gpus": []}
    second = copy.deepcopy(first)
    second["run"]["machine"]["cpu"]["physical_cores"] = 4.0
    with pytest.raises(RaybenchError, match=r"line 2: run.machine.cpu.physical_cores: must be a whole number"):
        results.parse_records(lines_of(first, second), "r.jsonl")
    first["run"]["settings"], second["run"]["settings"] = {"n": 1}, {"n": True}
    second["run"]["machine"]["cpu"]["physical_cores"] = 4
    # both are valid settings; the second is checked as its own (and passes), not taken as the first
    assert len(results.parse_records(lines_of(first, second), "r.jsonl")) == 2


SUMMARY_CONTRADICTED = {
    "p5 above p95": set_at(["frame_ms", "p5"], 1000.0),
    "median above max": set_at(["frame_ms", "median"], 1000.0),
    "mean above max": set_at(["frame_ms", "mean"], 1000.0),
    "min above p5": set_at(["frame_ms", "min"], 9.99),
    "a sample past max": set_at(["samples_ms", 3], 1000.0),
    "samples of another median": lambda r: r.update(samples_ms=[x * 2 for x in r["samples_ms"]]),
}


@pytest.mark.parametrize("name", SUMMARY_CONTRADICTED)
def test_a_summary_that_contradicts_itself_or_its_samples_is_refused(rng, name):
    """p5 > p95, a median past max, samples that cannot be the summary's: the
    reader took them, and compare judged the samples while printing the summary."""
    record = full(point(frames(rng, 10.0, 20), 100))
    record["frame_ms"].update(min=5.0, p5=10.0, median=10.0, p95=10.0, max=20.0, mean=10.0)
    record["samples_ms"] = [5.0] + [10.0] * 18 + [20.0]
    results.check_record(record, "record")
    SUMMARY_CONTRADICTED[name](record)
    with pytest.raises(RaybenchError, match=r"^record: (frame_ms|samples_ms)"):
        results.check_record(record, "record")


def test_parts_are_held_to_their_samples_too(rng):
    part = {
        "suite": "parts",
        "quantity": "bvh-build",
        "device": "cpu",
        "samples": 3,
        "time_ms": {"median": 2.0, "p5": 1.0, "p95": 3.0},
        "samples_ms": [1.0, 2.0, 3.0],
        "run": point([1.0], 1)["run"],
    }
    results.check_record(full(part), "record")
    part["time_ms"]["median"] = 5.0
    with pytest.raises(RaybenchError, match="time_ms: must be in order"):
        results.check_record(full(part), "record")


def test_a_lone_surrogate_is_one_line_everywhere(tmp_path, rng, capsys):
    """Half a UTF-16 pair in a key or a value: compare raised UnicodeEncodeError
    and report a matplotlib TypeError. A whole pair (an emoji escaped) is a character."""
    good = point(frames(rng, 10.0, 20), 100)
    pair = copy.deepcopy(good)
    pair["run"]["machine"]["cpu"]["model"] = "\ud83d\ude00 CPU"
    (tmp_path / "pair.jsonl").write_text(lines_of(pair))
    assert len(results.read(tmp_path / "pair.jsonl")) == 1
    halves = [lambda r: r["options"].update({"\ud800": 1}), set_at(["run", "machine", "cpu", "model"], "x\udfffy")]
    for half in halves:
        bad = copy.deepcopy(good)
        half(bad)
        path = tmp_path / "bad.jsonl"
        path.write_text(lines_of(bad))  # json.dumps writes the half pair as its \\u escape, as an editor may
        for args in (["compare", str(path), str(path)], ["report", str(path), "-o", str(tmp_path / "rep")]):
            assert run(args) == 2, args
            err = capsys.readouterr().err
            assert err.count("\n") == 1 and "half of a UTF-16 pair" in err, err
        assert not (tmp_path / "rep").exists()


def test_only_a_cut_record_may_end_a_file_without_a_newline(rng):
    """A last line without its newline was skipped with a warning whatever it
    held; now only the start of a record the writer wrote is, and other text
    is an error as it is on any other line."""
    text = lines_of(point(frames(rng, 10.0, 20), 100))
    cut = lines_of(point(frames(rng, 10.0, 20), 200))[:70]
    with pytest.warns(UserWarning, match="line 2 is cut short"):
        assert len(results.parse_records(text + cut, "r.jsonl")) == 1
    for garbage in ("hello", '{"hello": 1', "[1, 2"):
        with pytest.raises(RaybenchError, match="line 2"):
            results.parse_records(text + garbage, "r.jsonl")
        with pytest.raises(RaybenchError, match="line 2"):
            results.parse_records(text + garbage + "\n", "r.jsonl")


def test_a_repeat_is_folded_into_its_point(tmp_path, rng):
    """Bench writes each repeat of a headline point as a line of its own, as it is timed; the
    reader folds it into its point's record (its "repeats"), so every reader sees one record a
    point, and refuses a repeat of a point that no earlier line holds."""
    first = point(frames(rng, 10.0, 20), 100, options={"accel": "none", "kernel": "fast"})
    other = point(frames(rng, 40.0, 20), 500, options={"accel": "none", "kernel": "fast"})
    again = {**point(frames(rng, 11.0, 30), 100, options={"accel": "none", "kernel": "fast"}), "repeat": 1}
    path = tmp_path / "r.jsonl"
    path.write_text("".join(json.dumps(full(r)) + "\n" for r in (first, other, again)))
    for r in (first, other, again):
        assert VALIDATOR.is_valid(full(r))
    got = results.read(path)
    assert len(got) == 2 and "repeat" not in got[0]
    (kept,) = got[0]["repeats"]
    assert kept["frames"] == 30 and kept["samples_ms"] == again["samples_ms"]
    assert VALIDATOR.is_valid(full(got[0]))  # a folded record is a valid record too (a file written from it)
    path.write_text("".join(json.dumps(full(r)) + "\n" for r in (other, again)))
    with pytest.raises(RaybenchError, match=r"line 2: repeat 1 of a point that no line before it holds"):
        results.read(path)
