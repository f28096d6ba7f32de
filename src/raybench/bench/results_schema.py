"""The results record's rules (bench.results describes its fields): the
limits on its numbers and text, the checkers, each of which carries its rule
as JSON Schema, and the record's parts written with them. bench.results
applies them (check_record) and publishes them (schema())."""

from __future__ import annotations

import re

import numpy as np

from ..backends.limits import MAX_SIDE
from . import pictures
from .suites import RECORDS

# Every number a record holds is a count, a time or a rate far below this:
# larger ones are hand-edited, and would overflow the report's sums and fits.
MAX_NUMBER = 1e15
# ... and every non-zero one far above this (1e-9 ms is a picosecond): smaller
# ones are hand-edited too, and would print as hundreds of digits.
MIN_NUMBER = 1e-9
MAX_TEXT = 300
# Names the report prints as they are and uses in file names: what bench --label allows.
# A leading letter or digit: "." and ".." would be folders that are not new.
NAME = re.compile(r"[A-Za-z0-9][A-Za-z0-9._-]{0,63}")
# Option values: "one per row", "2x cores", "constant", an adapter's name.
OPTION_TEXT = re.compile(r"[A-Za-z0-9 ._:,/()+-]{0,120}")


# A checker takes a value and returns None, or raises _Bad; an object's checker
# puts the field's name in front of the path as _Bad passes it, so the path is
# only ever built for the one field that fails (reading stays fast). Each
# checker also carries its rule as JSON Schema (.json), from which schema()
# builds the published schema: one statement of the rules, two readings.


class _Bad(Exception):
    def __init__(self, what: str, value, path: str = ""):
        self.what, self.value, self.path = what, value, path

    def at(self, key: str) -> _Bad:
        self.path = key + ("" if not self.path or self.path.startswith("[") else ".") + self.path
        return self


def _rule(json_schema: dict):
    """Attach a checker's rule as JSON Schema."""

    def attach(check):
        check.json = json_schema
        return check

    return attach


@_rule({"type": "string", "maxLength": MAX_TEXT, "pattern": "^[^\\n]*$"})
def _text(value):
    if not isinstance(value, str) or len(value) > MAX_TEXT or "\n" in value:
        raise _Bad(f"one line of text, at most {MAX_TEXT} characters", value)


@_rule({"type": "string", "pattern": "^" + NAME.pattern + "$"})
def _name(value):
    if not isinstance(value, str) or not NAME.fullmatch(value):
        raise _Bad("a name of letters, digits, '.', '_' and '-', starting with a letter or digit", value)


def _whole(low: int, high: float):
    """A whole number from low to high (no true for 1, no 2.0)."""

    @_rule({"type": "integer", "minimum": low, "maximum": high})
    def check(value):
        if isinstance(value, bool) or not isinstance(value, int) or not low <= value <= high:
            raise _Bad(f"a whole number from {low:g} to {high:g}", value)

    return check


@_rule({"type": "string", "maxLength": pictures.MAX_CHARS, "pattern": "^" + pictures.PATTERN.pattern + "$"})
def _picture(value):
    if not isinstance(value, str) or len(value) > pictures.MAX_CHARS or not pictures.PATTERN.fullmatch(value):
        raise _Bad(f"a JPEG as a data: URI ({pictures.PREFIX}...), at most {pictures.MAX_CHARS:,} characters", value)


_count = _whole(0, MAX_NUMBER)
_size = _whole(1, MAX_SIDE)


@_rule({"type": "number", "anyOf": [{"const": 0}, {"minimum": MIN_NUMBER, "maximum": MAX_NUMBER}]})
def _number(value):
    if (
        isinstance(value, bool)
        or not isinstance(value, (int, float))
        or not (value == 0 or MIN_NUMBER <= value <= MAX_NUMBER)
    ):
        raise _Bad(f"0, or a number from {MIN_NUMBER:g} to {MAX_NUMBER:g}", value)


@_rule({"type": "number", "minimum": MIN_NUMBER, "maximum": MAX_NUMBER})
def _time(value):
    """A measured time: every ratio in the report divides by one, and no real frame takes 0 ms."""
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not (MIN_NUMBER <= value <= MAX_NUMBER):
        raise _Bad(f"a time from {MIN_NUMBER:g} to {MAX_NUMBER:g}", value)


def _times_all_fine(values: list) -> bool:
    """Whether every one of values passes _time, at NumPy's speed (a record keeps up to
    1,000 frame times, and a results file thousands of records); False sends the list
    to the check item by item, which names the first that fails."""
    if not set(map(type, values)) <= {float, int}:  # (no bool, no NumPy scalar)
        return False
    try:
        a = np.asarray(values, dtype=np.float64)
    except OverflowError:
        return False
    fine = bool(((a >= MIN_NUMBER) & (a <= MAX_NUMBER)).all())
    if fine:
        global _last_times
        _last_times = (values, a)
    return fine


_time.many = _times_all_fine
# The last list _times_all_fine passed, and its array: the reader compares a record's
# samples with its summary, then keeps them as an array (compact): one conversion of
# a record's thousand times, not three. Held with the list, so the identity is its own;
# forgotten before each record's checks, so a list changed in place since is converted anew.
_last_times: tuple = (None, None)


def forget_times() -> None:
    global _last_times
    _last_times = (None, None)


def times_array(values) -> np.ndarray:
    """values (a list of times) as a float64 array, converted once where just checked."""
    checked, a = _last_times
    return a if checked is values else np.asarray(values, dtype=np.float64)


def _one_of(*choices):
    @_rule({"enum": list(choices)})
    def check(value):
        if isinstance(value, bool) or isinstance(value, (list, dict)) or value not in choices:
            raise _Bad("one of " + ", ".join(map(str, choices)), value)

    return check


def _or_null(spec):
    spec = _compile(spec)

    @_rule({"anyOf": [spec.json, {"type": "null"}]})
    def check(value):
        if value is not None:
            spec(value)

    return check


def _list(spec, most: int = 10_000_000, least: int = 0):
    spec = _compile(spec)

    many = getattr(spec, "many", None)

    @_rule({"type": "array", "items": spec.json, "minItems": least, "maxItems": most})
    def check(value):
        if not isinstance(value, list) or not least <= len(value) <= most:
            raise _Bad(f"a list of {least:,} to {most:,}" if least else f"a list of at most {most:,}", value)
        if many is not None and len(value) > 8 and many(value):
            return
        for i, item in enumerate(value):
            try:
                spec(item)
            except _Bad as bad:
                raise bad.at(f"[{i}]") from None

    return check


def _object_of(spec):
    """An object whose every value matches spec (settings, versions)."""
    spec = _compile(spec)

    @_rule({"type": "object", "additionalProperties": spec.json})
    def check(value):
        if not isinstance(value, dict):
            raise _Bad("an object", value)
        for key, item in value.items():
            try:
                spec(item)
            except _Bad as bad:
                raise bad.at(key) from None

    return check


def _compile(spec, named: dict | None = None, rest=None):
    """A dict of field -> spec (a key ending in "?" may be missing; fields not
    named pass, for newer writers, or must match rest where given) becomes the
    checker of such an object."""
    if callable(spec):
        return spec
    fields = [(key.rstrip("?"), key.endswith("?"), _compile(field)) for key, field in spec.items()]
    json_schema = {
        "type": "object",
        "properties": {key: field.json for key, _, field in fields},
        "required": [key for key, optional, _ in fields if not optional],
    }
    if rest is not None:
        json_schema["additionalProperties"] = rest.json

    @_rule(json_schema)
    def check(value):
        if not isinstance(value, dict):
            raise _Bad("an object", value)
        for key, optional, field in fields:
            if key in value:
                try:
                    field(value[key])
                except _Bad as bad:
                    raise bad.at(key) from None
            elif not optional:
                raise _Bad("present", "nothing").at(key)
        if rest is not None:  # (optional fields make the count of value's keys no guide to the names)
            for key, item in value.items():
                if key not in spec and key + "?" not in spec:
                    try:
                        rest(item)
                    except _Bad as bad:
                        raise bad.at(key) from None

    return check


@_rule({"type": "string", "pattern": "^" + OPTION_TEXT.pattern + "$"})
def _option_text(value):
    if not isinstance(value, str) or not OPTION_TEXT.fullmatch(value):
        raise _Bad("a short text of letters, digits and spaces", value)


_pair = _list(_size, 2, 2)


@_rule({"anyOf": [_option_text.json, _list(_count, 16).json, _number.json, {"type": ["boolean", "null"]}]})
def _option(value):
    """An option no reader knows yet (a newer writer's): any plain value."""
    if isinstance(value, str):
        _option_text(value)
    elif isinstance(value, list):
        _list(_count, 16)(value)
    elif value is not None and not isinstance(value, bool):
        _number(value)


@_rule({"type": "boolean"})
def _flag(value):
    if not isinstance(value, bool):
        raise _Bad("true or false", value)


# Every option a reader (the report, compare, the suites) interprets, with the
# values it can take; any other name is _option's, kept for newer writers.
OPTIONS = _compile(
    {
        "threads?": _whole(1, 1_000_000),
        "block?": _pair,
        "workgroup?": _pair,
        "adapter?": _option_text,
        "accel?": _one_of("bvh", "none"),
        "kernel?": _one_of("fast", "simple"),
        "count?": _one_of("constant", "runtime"),
        "build?": _one_of("host", "gpu"),
        "label?": _option_text,
        "cap_s?": _time,
        "layout?": _one_of("even", "dense", "clusters", "deep"),
        "tree_width?": _one_of(2, 4),
        "shading?": _one_of("thesis", "whitted"),
        "depth?": _whole(0, 64),
        "shadow_samples?": _whole(1, 64),
        "schedule?": _one_of("wavefront", "pixel"),
        "workers?": _whole(1, 100_000),
        "job?": _one_of("frame", "sequence"),
        "frames?": _whole(1, 100_000_000),
        "rows?": _size,
        "tasks?": _whole(1, 100_000_000),
        "shared?": _flag,
        "threads_per_worker?": _whole(1, 1_000_000),
        "motion?": _option_text,
        "policy?": _option_text,
        "quality?": _option_text,
        "walk?": _option_text,
        "delivery?": _option_text,
        "version?": _option_text,
        # the meshes suite's: which generated mesh (bench/meshes.py) and its triangle count
        "mesh?": _one_of("icosphere", "random"),
        "triangles?": _count,
        # the scenes suite's molecules: which example, how many copies side by side, their atoms, the style
        "molecule?": _option_text,
        "copies?": _whole(1, 100_000),
        "atoms?": _count,
        "style?": _one_of("spacefill", "ball-and-stick"),
    },
    rest=_option,
)


def _plain(value):
    """A setting as the runner writes it: text, a number, a flag, null, or a list of those."""
    if isinstance(value, list):
        _list(_plain, 64)(value)
    elif isinstance(value, str):
        _text(value)
    elif value is not None and not isinstance(value, bool):
        _number(value)


_plain.json = {"$ref": "#/$defs/plain"}
PLAIN = {
    "anyOf": [
        _text.json,
        _number.json,
        {"type": ["boolean", "null"]},
        {"type": "array", "maxItems": 64, "items": {"$ref": "#/$defs/plain"}},
    ]
}

TIMES = {"median": _time, "p5": _time, "p95": _time, "mean?": _time, "min?": _time, "max?": _time}
MACHINE = {
    "os?": _text,
    "cpu?": {
        "model?": _text,
        "arch?": _text,
        "physical_cores?": _or_null(_count),
        "logical_cpus?": _or_null(_count),
        "clock_ghz?": _or_null(_number),
        "simd?": _or_null(_text),
        "simd_bits?": _or_null(_count),
        "fp32_lanes?": _or_null(_count),
        "fma_units_per_core?": _or_null(_count),
        "fp32_gflops?": _or_null(_number),
        "memory_gib?": _or_null(_number),
    },
    "gpus?": _list(
        {
            "name?": _text,
            "compute_capability?": _text,
            "multiprocessors?": _or_null(_count),
            "clock_ghz?": _or_null(_number),
            "memory_clock_ghz?": _or_null(_number),
            "memory_gib?": _or_null(_number),
            "fp32_lanes_per_sm?": _or_null(_count),
            "fp32_gflops?": _or_null(_number),
            "driver?": _or_null(_text),
        },
        64,
    ),
    "wgpu_adapters?": _list(_object_of(_or_null(_plain)), 64),
    "versions?": _object_of(_or_null(_text)),
}
RUN = _compile(
    {
        "id?": _text,
        "date?": _text,
        "git_commit?": _or_null(_text),
        "label": _name,
        "argv?": _list(_text, 256),
        "settings?": _object_of(_plain),
        "machine": MACHINE,
    }
)
SUITES = RECORDS  # every registered suite's record suites (suites.REGISTRY)
DEVICES = ("cpu", "cuda", "wgpu")
POINT = _compile(
    {
        "suite": _one_of(*SUITES),
        "test?": _or_null(_whole(1, 7)),
        "device": _one_of(*DEVICES),
        "width": _size,
        "height": _size,
        "spheres": _count,
        "options?": OPTIONS,
        "adapter?": _object_of(_or_null(_plain)),
        "walk?": _or_null(_text),
        # the k-th time this point was timed again in its run (the headline's points)
        "repeat?": _whole(1, 64),
    }
)
MEASURED = _compile(
    {
        "frames?": _count,
        "frame_ms": TIMES,
        # the frames' own times (at most stats.MAX_SAMPLES, evenly strided): compare's bootstrap
        "samples_ms?": _list(_time, 100_000),
        # its repeats' frames, folded in as results.read reads them
        "repeats?": _list({"frames?": _count, "frame_ms": TIMES, "samples_ms?": _list(_time, 100_000)}, 64),
        "kernel_ms?": _or_null(TIMES),
        "first_frame_s?": _or_null(_number),
        "compile_s?": _or_null(_number),
        "build_s?": _or_null(_number),
        "rays_per_s?": _or_null(_number),
        "tests_per_s?": _or_null(_number),
        # Whitted shading's (the secondary suite): the rays the kernels counted
        "rays?": {"primary": _count, "shadow": _count, "reflection": _count, "refraction": _count},
        "rays_per_frame?": _count,
        "kernel_rays_per_s?": _or_null(_number),
        # the multi-gpu suite's (its workers' throughput) and the dynamic suite's
        "frames_per_s?": _number,
        # the dynamic suite's: the tree's update in each frame
        "update_ms?": TIMES,
        "updates?": {"refit?": _count, "build?": _count},
        "update_share?": _number,
        # the scenes suite's: the frame it traced, small (bench.pictures), for the report
        "picture?": _picture,
    }
)
# suite "parts": a quantity timed apart from any suite's frames (benchmarks/_harness.part)
PART = _compile(
    {
        "quantity": _name,
        "device": _one_of(*DEVICES),
        "spheres?": _count,
        "width?": _size,
        "height?": _size,
        "options?": OPTIONS,
        "samples?": _count,
        "time_ms": TIMES,
        "samples_ms?": _list(_time, 100_000),
        "values?": _object_of(_or_null(_number)),
    }
)
SKIPPED = _compile({"skipped": _text, "predicted_ms?": _or_null(_number)})
SERIES = _compile(
    {"series": {"spheres": _list(_count), "frame_ms": _list(_time), "kernel_ms?": _or_null(_list(_time))}}
)
