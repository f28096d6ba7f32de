"""files.parse reads JSON with orjson where orjson gives the standard library's value,
and with the standard library elsewhere: what a document reads as, and the message of
one that is refused, must be the standard library's, whichever parser ran."""

from __future__ import annotations

import json

from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from raybench import files
from raybench.bench import results
from raybench.errors import RaybenchError


def reference(text: str) -> str:
    """What the standard library alone made of text: the value's repr (4.0 is not 4,
    true is not 1), or the one line the reader gives."""
    try:
        return repr(files._DECODER.decode(text))
    except files.DuplicateKey as exc:
        return f"w: {exc}"
    except json.JSONDecodeError as exc:
        return f"w: not valid JSON: {exc.msg} at line {exc.lineno} column {exc.colno}"
    except ValueError as exc:
        return f"w: not valid JSON: {exc}".split("\n")[0]


def parsed(text: str) -> str:
    try:
        return repr(files.parse(text, "w"))
    except RaybenchError as exc:
        return str(exc)


# Where orjson and the standard library part: integers past 64 bits, a key twice,
# NaN and infinities, a lone surrogate, a ':' written as an escape.
ATOMS = [
    "18446744073709551616", "-9223372036854775809", "18446744073709551615", "1" * 30, "1e400", "-1e400",
    "NaN", "Infinity", "-0", "-0.0", "4", "4.0", "5e-324", "1.0e-330", "true", "null",
    '"\\ud800"', '"\\udc00x"', '"\\ud83d\\ude00"', '"\\u003a"', '"\\u003A"', '"a:b"', '"\\\\u003a"', '"\\u0000"',
]  # fmt: skip
KEYS = ["a", "b", "\\u0061", "a:b", "\\u003a"]


def documents():
    atom = st.one_of(
        st.sampled_from(ATOMS),
        st.floats(allow_nan=False, allow_infinity=False).map(repr),
        st.integers(-(2**70), 2**70).map(str),
        st.text(max_size=6).map(json.dumps),
    )
    return st.recursive(
        atom,
        lambda inner: st.one_of(
            st.lists(inner, max_size=5).map(lambda items: "[" + ",".join(items) + "]"),
            st.lists(st.tuples(st.sampled_from(KEYS), inner), max_size=4).map(
                lambda pairs: "{" + ",".join(f'"{k}":{v}' for k, v in pairs) + "}"
            ),
        ),
        max_leaves=12,
    )


@settings(max_examples=400, derandomize=True, database=None, suppress_health_check=[HealthCheck.too_slow])
@given(documents(), st.sampled_from(["", " ", "\n", "x", ",", "]"]))
def test_parse_reads_as_the_standard_library_does(text, tail):
    assert parsed(text + tail) == reference(text + tail)


def test_a_results_record_is_read_by_the_fast_parser():
    """The point of the fast path: a record as the writer makes it takes it."""
    run = {"date": "2026-12-03T00:00:00+00:00", "cpu": "AMD: EPYC"}
    record = {"format": results.FORMAT, "version": results.VERSION, "samples_ms": [4.0123, 5.5, 1e-05], "run": run}
    line = json.dumps(record, separators=(",", ":"))
    assert files._fast(line) is not files._REFERENCE
    assert parsed(line) == repr(record)
