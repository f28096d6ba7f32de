"""Checking a JSON document's fields (a scene file's), each fault one line
naming the field's path: no unknown key, numbers finite and of the count asked."""

from __future__ import annotations

import json
import math

from .errors import RaybenchError


def no_unknown(obj: dict, allowed: set, prefix: str) -> None:
    unknown = sorted(set(obj) - allowed)
    if unknown:
        key = unknown[0] if unknown[0].isidentifier() else short(json.dumps(unknown[0]))
        raise RaybenchError(f"{prefix}{key}: unknown field (allowed: {', '.join(sorted(allowed))})")


def numbers(value, count, where):
    """Check a JSON number (count None) or a list of count numbers; return floats."""
    values = [value] if count is None else value
    if count is not None and (not isinstance(value, list) or len(value) != count):
        raise RaybenchError(f"{where}: must be a list of {count} numbers, got {short(json.dumps(value))}")
    for v in values:
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not finite(v):
            raise RaybenchError(f"{where}: must be a finite number, got {short(json.dumps(v))}")
    return values[0] if count is None else values


def finite(v) -> bool:
    try:
        return math.isfinite(v)
    except OverflowError:  # a JSON integer too large for a float
        return False


def short(text: str) -> str:
    return text if len(text) <= 40 else text[:37] + "..."
