"""Reference results shipped with raybench: records measured on other machines
(an NVIDIA H200 and its 16-core host, an H100 and its host, a 2-core EPYC
without a GPU), each with its machine description, date and commit, so that a
run on a machine without some device can still be placed against one that has
it. references.jsonl.gz is made by benchmarks/make_references.py from the
records committed under benchmarks/results/, and read here through the same
schema as any results file."""

from __future__ import annotations

import functools
import gzip
from importlib import resources

from ..bench import results

NAME = "references.jsonl.gz"


@functools.cache
def _records() -> tuple[dict, ...]:
    data = resources.files(__name__).joinpath(NAME).read_bytes()
    return tuple(results.parse_records(gzip.decompress(data).decode("utf-8"), f"raybench references ({NAME})"))


def load() -> list[dict]:
    """Every reference record (fresh copies: a caller may change them)."""
    import copy

    return copy.deepcopy(list(_records()))


def machines() -> dict[str, list[dict]]:
    """The reference records by machine (run label), in the file's order."""
    out: dict[str, list[dict]] = {}
    for record in load():
        out.setdefault(record["run"]["label"], []).append(record)
    return out
