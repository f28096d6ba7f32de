"""benchmarks/_harness.py: rounds taken in turn, and records that `raybench report` reads."""

import argparse
import importlib.util
import json
from pathlib import Path

import pytest

from raybench.bench import results

_spec = importlib.util.spec_from_file_location(
    "_harness", Path(__file__).resolve().parent.parent / "benchmarks" / "_harness.py"
)
harness = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(harness)


def test_paired_turns_the_order_each_round():
    calls = []
    samples = harness.paired({"a": lambda: calls.append("a") or 1.0, "b": lambda: calls.append("b") or 2.0}, 3)
    assert calls == ["a", "b", "b", "a", "a", "b"]
    assert samples == {"a": [1.0, 1.0, 1.0], "b": [2.0, 2.0, 2.0]}


def _args(*argv):
    parser = argparse.ArgumentParser()
    harness.add_common(parser)
    args = parser.parse_args(list(argv))
    harness.check_common(parser, args)
    return args


def test_records_are_the_schemas_and_stamped(tmp_path, capsys):
    out = tmp_path / "r.jsonl"
    with harness.Records("probe", _args("--out", str(out), "--label", "probe-a"), {"frames": 3}) as records:
        records.write(harness.point("scaling", "cpu", 64, 32, 10, {"accel": "bvh"}, [3.0, 1.0, 2.0], None))
        records.write(harness.point("scaling", "cuda", 64, 32, 10, {"accel": "bvh"}, [2.0, 2.5], [1.0, 1.5]))
    read = results.read(out)
    assert [r["device"] for r in read] == ["cpu", "cuda"]
    assert read[0]["frame_ms"]["median"] == 2.0 and read[0]["frame_ms"]["p5"] < 2.0 < read[0]["frame_ms"]["p95"]
    assert read[0]["rays_per_s"] == 64 * 32 / 2e-3 and read[1]["kernel_ms"]["median"] == 1.25
    run = read[0]["run"]
    assert run["label"] == "probe-a" and run["argv"][0] == "benchmarks/probe.py" and "cpu" in run["machine"]
    printed = [json.loads(line) for line in capsys.readouterr().out.splitlines()]
    assert printed == read


def test_a_record_outside_the_schema_is_refused(tmp_path):
    with harness.Records("probe", _args("--out", str(tmp_path / "r.jsonl")), {}) as records:
        bad = harness.point("scaling", "gpu", 64, 32, 10, {}, [1.0])  # no such device
        with pytest.raises(Exception, match="device"):
            records.write(bad)
    assert not (tmp_path / "r.jsonl").exists()


def test_bad_common_flags_are_refused():
    with pytest.raises(SystemExit):
        _args("--frames", "0")
    with pytest.raises(SystemExit):
        _args("--label", "has space")


def test_paired_takes_a_turns_list_of_samples():
    samples = harness.paired({"a": lambda: [1.0, 2.0], "b": lambda: 3.0}, 2)
    assert samples == {"a": [1.0, 2.0, 1.0, 2.0], "b": [3.0, 3.0]}


def test_parts_records_are_the_schemas(tmp_path):
    """What is no suite's frame (a build, a start-up) is a record of the "parts" suite: its
    quantity, its time's median, p5 and p95, and figures by name; report reads it."""
    out = tmp_path / "r.jsonl"
    with harness.Records("probe", _args("--out", str(out)), {}) as records:
        records.write(harness.part("bvh-build", "cpu", [3.0, 1.0, 2.0], spheres=10, values={"depth": 4}))
        records.write(harness.part("startup-cold", "cuda", [900.0], width=64, height=32, options={"kernel": None}))
        with pytest.raises(Exception, match="quantity"):
            records.write(harness.part("a build", "cpu", [1.0]))
    read = results.read(out)
    assert read[0]["quantity"] == "bvh-build" and read[0]["time_ms"]["median"] == 2.0 and read[0]["samples"] == 3
    assert read[0]["values"] == {"depth": 4} and "width" not in read[0] and read[1]["options"] == {}
    assert read[0]["run"]["settings"]["raybench"].endswith("__init__.py")
    assert len(harness.timings(lambda: None, 4)) == 4
