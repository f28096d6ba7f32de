"""Summaries of timing samples, and straight-line fits."""

from __future__ import annotations

import math

import numpy as np


def summarize(samples_ms) -> dict:
    """mean, median, p5, p95 of frame times in milliseconds."""
    a = np.asarray(samples_ms, dtype=np.float64)
    if a.size == 0:
        raise ValueError("no samples")
    p5, median, p95 = np.percentile(a, [5, 50, 95])
    return {
        "mean": float(a.mean()),
        "median": float(median),
        "p5": float(p5),
        "p95": float(p95),
        "min": float(a.min()),
        "max": float(a.max()),
    }


# Frames a record keeps for raybench compare's bootstrap: a GPU point can time
# tens of thousands in its seconds; an even stride over them keeps any drift.
MAX_SAMPLES = 1000


def kept_samples(samples_ms) -> list[float]:
    """The frame times a record keeps (samples_ms): at most MAX_SAMPLES, evenly
    strided, each to 5 significant digits (far finer than any run's noise)."""
    a = np.asarray(samples_ms, dtype=np.float64)
    if a.size > MAX_SAMPLES:
        a = a[np.linspace(0, a.size - 1, MAX_SAMPLES).round().astype(np.int64)]
    return [float(f"{x:.5g}") for x in a]


def linear_fit(x, y) -> dict:
    """Least-squares y = slope * x + intercept, with R^2 (1 for a perfect line;
    nan where y does not vary)."""
    x = np.asarray(x, dtype=np.float64)
    y = np.asarray(y, dtype=np.float64)
    if x.size < 2 or np.ptp(x) == 0:
        raise ValueError("a line needs at least two distinct x")
    slope, intercept = np.polyfit(x, y, 1)
    residual = y - (slope * x + intercept)
    total = float(((y - y.mean()) ** 2).sum())
    r2 = 1.0 - float((residual**2).sum()) / total if total > 0 else math.nan
    return {"slope": float(slope), "intercept": float(intercept), "r2": r2, "n": int(x.size)}
