"""Which points each suite measures.

A Point is one thing to time: a device, a size, a scene of n spheres, and the
device options. The thesis's tests 1 to 6 are the sweep of sphere counts at
three resolutions (1-3 on the GPU, 4-6 on the CPU); test 7 is the ramp.
"""

from __future__ import annotations

import os
from dataclasses import dataclass, field

from ..backends.limits import FAST_MAX_THREADS
from ..errors import RaybenchError

SUITES = ("thesis", "constant-vs-runtime", "tuning")
THESIS_SIZES = ((800, 600), (1280, 800), (1680, 1050))
THESIS_COUNTS = tuple(range(100, 1001, 100))
TUNING_SIZE = (1680, 1050)
TUNING_SPHERES = 1000
BLOCKS = ((2, 2), (4, 4), (8, 8), (16, 16), (32, 32), (32, 8), (8, 32), (64, 4), (128, 2), (256, 1))
CONSTANT_COUNTS = (100, 250, 500, 1000)
RAMP_SIZE = (800, 600)
RAMP = (10, 1000, 10)  # first, last, step: the thesis's test 7


@dataclass(frozen=True)
class Point:
    suite: str
    device: str
    width: int
    height: int
    spheres: int
    options: dict = field(default_factory=dict, hash=False)
    test: int | None = None
    # test7 only: the sphere counts of its frames, one per frame
    ramp: tuple[int, ...] | None = None

    def describe(self) -> str:
        extra = "".join(f" {k}={_fmt(v)}" for k, v in self.options.items() if k != "label")
        label = f" ({self.options['label']})" if "label" in self.options else ""
        what = f"test 7 ramp {self.ramp[0]}..{self.ramp[-1]}" if self.ramp else f"{self.spheres} spheres"
        test = f"test {self.test} " if self.test and not self.ramp else ""
        return f"{self.suite} {test}{self.device} {self.width}x{self.height} {what}{extra}{label}"


def _fmt(value) -> str:
    return "x".join(map(str, value)) if isinstance(value, (list, tuple)) else str(value)


def thread_settings(cores: int, height: int) -> list[tuple[str, int]]:
    """The thesis's CPU tuning: 1 thread, half the cores, all cores, twice the
    cores, and one thread per image row."""
    settings = [("1 thread", 1), ("half the cores", max(1, cores // 2)), ("all cores", cores),
                ("2x cores", 2 * cores), ("one per row", height)]
    seen, out = set(), []
    for label, n in settings:
        if n not in seen:
            seen.add(n)
            out.append((label, n))
    return out


GPUS = ("cuda", "wgpu")


def _runs(kernels, devices, wgpu: dict):
    """(kernel, device, extra options) for the thesis and tuning suites: cpu and
    cuda once per kernel; wgpu once, with its only kernel (simple) and its
    options (the adapter named)."""
    out = [(k, d, {}) for k in kernels for d in devices if d != "wgpu"]
    if "wgpu" in devices:
        out.append(("simple", "wgpu", dict(wgpu)))
    return out


def points(suites, devices, quick: bool = False, cores: int | None = None, kernels=("fast",),
           wgpu: dict | None = None, max_invocations: int = 1024) -> list[Point]:
    """Every point of the chosen suites on the chosen devices (the thesis and
    tuning suites once per kernel), in run order. wgpu: that device's options
    ({"adapter": name}); max_invocations: its adapter's workgroup limit, which
    bounds the tuning suite's shapes."""
    for suite in suites:
        if suite not in SUITES:
            raise RaybenchError(f"suite: unknown suite {suite!r}; choose from {', '.join(SUITES)}")
    cores = cores or os.cpu_count() or 1
    out: list[Point] = []
    if "thesis" in suites:
        sizes = THESIS_SIZES[:1] if quick else THESIS_SIZES
        counts = (100, 500, 1000) if quick else THESIS_COUNTS
        for kernel, device, extra in _runs(kernels, devices, wgpu or {}):
            for i, (w, h) in enumerate(sizes):
                test = (1 if device in GPUS else 4) + i
                out += [Point("thesis", device, w, h, n, {"kernel": kernel, **extra}, test=test) for n in counts]
        first, last, step = (10, 200, 10) if quick else RAMP
        ramp = tuple(range(first, last + 1, step))
        w, h = (320, 240) if quick else RAMP_SIZE
        out += [Point("test7", device, w, h, ramp[-1], {"kernel": kernel, **extra}, test=7, ramp=ramp)
                for kernel, device, extra in _runs(kernels, devices, wgpu or {})]
    if "constant-vs-runtime" in suites:
        counts = (100, 500) if quick else CONSTANT_COUNTS
        w, h = (640, 480) if quick else THESIS_SIZES[-1]
        for device in (d for d in devices if d != "wgpu"):  # wgpu has no compile-time count (yet)
            for n in counts:
                for mode in ("constant", "runtime"):
                    # the simple kernel: the only one with a compile-time count
                    out.append(Point("constant-vs-runtime", device, w, h, n, {"count": mode, "kernel": "simple"}))
    if "tuning" in suites:
        w, h = (640, 480) if quick else TUNING_SIZE
        n = 300 if quick else TUNING_SPHERES
        for kernel, device, extra in _runs(kernels, devices, wgpu or {}):
            if device == "cpu":
                settings = thread_settings(cores, h)
                if quick:
                    settings = [s for s in settings if s[0] in ("1 thread", "all cores", "2x cores")]
                out += [Point("tuning", "cpu", w, h, n, {"threads": t, "label": label, "kernel": kernel})
                        for label, t in settings]
            else:
                blocks = ((8, 8), (16, 16), (32, 32), (32, 8)) if quick else BLOCKS
                if kernel == "fast":  # larger blocks cannot launch (limits.FAST_MAX_THREADS)
                    blocks = tuple(b for b in blocks if b[0] * b[1] <= FAST_MAX_THREADS)
                if device == "wgpu":
                    blocks = tuple(b for b in blocks if b[0] * b[1] <= max_invocations)
                    out += [Point("tuning", device, w, h, n, {"workgroup": list(b), "label": f"{b[0]}x{b[1]}",
                                                              "kernel": kernel, **extra}) for b in blocks]
                    continue
                out += [Point("tuning", device, w, h, n, {"block": list(b), "label": f"{b[0]}x{b[1]}", "kernel": kernel})
                        for b in blocks]
    return out
