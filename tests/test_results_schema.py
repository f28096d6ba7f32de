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
