"""docs/architecture.md's worked examples run as written: each "how to add" ends
with a Python block that states what a newcomer relies on (a primitive's
answers, the walk's answer against brute force, a device's contract, a
suite's declaration), so the page cannot drift from the code."""

import re
from pathlib import Path

import pytest

PAGE = Path(__file__).resolve().parent.parent / "docs" / "architecture.md"
BLOCK = re.compile(r"^```python\n(.*?)^```", re.S | re.M)


def blocks() -> list[str]:
    return BLOCK.findall(PAGE.read_text(encoding="utf-8"))


def test_the_page_has_its_worked_examples():
    assert len(blocks()) == 4  # a primitive, a walk, a device, a suite


@pytest.mark.parametrize("number", range(4))
def test_a_worked_example_runs(number):
    code = blocks()[number]
    exec(compile(code, f"{PAGE.name}, example {number + 1}", "exec"), {"__name__": "example"})


def test_a_failing_example_fails():
    """An example whose claim is false raises: the runner does not swallow it."""
    with pytest.raises(AssertionError):
        exec(compile("assert 1 == 2", "example", "exec"), {})
