"""The committed results: every .jsonl under benchmarks/results/ is a record `raybench report`
reads, but for benchmarks/results/archive/, which holds only what it cannot (its README says
why), so that a file converted into the schema is not left there too."""

import warnings
from pathlib import Path

import pytest

from raybench.bench import results
from raybench.errors import RaybenchError

RESULTS = Path(__file__).resolve().parent.parent / "benchmarks" / "results"
ARCHIVE = RESULTS / "archive"
FILES = sorted(RESULTS.rglob("*.jsonl"))
LIVE = [p for p in FILES if ARCHIVE not in p.parents]
ARCHIVED = [p for p in FILES if ARCHIVE in p.parents]


def test_there_are_both():
    assert len(LIVE) >= 40 and len(ARCHIVED) >= 1


@pytest.mark.parametrize("path", LIVE, ids=lambda p: str(p.relative_to(RESULTS)))
def test_report_reads_every_committed_record(path):
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # not even a cut-short last line
        assert results.read(path)


@pytest.mark.parametrize("path", ARCHIVED, ids=lambda p: str(p.relative_to(RESULTS)))
def test_the_archive_holds_only_what_report_refuses(path):
    with pytest.raises(RaybenchError):
        results.read(path)
