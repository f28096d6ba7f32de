"""Numbers as the report writes them, in the verdicts, the charts and the
Markdown alike: significant digits, never exponent notation."""

from __future__ import annotations

import math


def fmt_num(x, sig: int = 3) -> str:
    """x to sig significant digits, never in exponent notation."""
    if x is None or (isinstance(x, float) and not math.isfinite(x)):
        return "–" if x is None or math.isnan(x) else ("∞" if x > 0 else "-∞")
    if x == 0:
        return "0"
    digits = max(0, sig - 1 - math.floor(math.log10(abs(x))))
    return f"{x:.{digits}f}"


def fmt_ms(x) -> str:
    return fmt_num(x, 3)


def fmt_x(x) -> str:
    return f"{fmt_num(x)}x"


def fmt_r2(x) -> str:
    return "nan (flat)" if x is None or math.isnan(x) else f"{x:.4f}"


def fmt_compile_s(x) -> str:
    """A compile time in s. Under a millisecond the kernels came from the disk cache: the figure
    is the cache's lookup, finer than anything a compile could mean, so it is said so."""
    if x is None:
        return "–"
    return "< 0.001 (from the cache)" if x < 1e-3 else fmt_num(x)


def fmt_slope(slope, spheres) -> str:
    """A fit's slope in ms a sphere. Where the whole series' range of spheres moves the frame by
    less than a microsecond, the slope is flat within what a frame's timing can tell, and the
    digits of its size would be noise: it reads as flat."""
    if slope is None:
        return "–"
    span = max(spheres) - min(spheres) if len(spheres) else 0
    if abs(slope) * span < 1e-3:
        return "flat (< 1 µs over the series)"
    return fmt_num(slope)
