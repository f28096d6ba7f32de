"""Progress as plain lines, for a run whose output is a file, a pipe or a CI log (rich's bar
draws only on a terminal): a line when a suite starts, a line for each point with what is
left, and, while one point takes long (a first compile, a slow device), a line at least every
HEARTBEAT_S seconds, so a log is never silent for a minute.

What is left is the remaining points' nominal time (their duration and warm-up) scaled by how
long the finished points took against theirs: compiling and slow frames show in it as soon as
one point has finished."""

from __future__ import annotations

import threading
import time
from collections.abc import Callable

HEARTBEAT_S = 45.0


def clock(seconds: float) -> str:
    seconds = max(0, round(seconds))
    return f"{seconds // 60}:{seconds % 60:02d}"


class Lines:
    """Call point(i, point) as each point starts and done(i) as it ends; close() at the end."""

    def __init__(self, echo: Callable[[str], None], points: list, weights: list[float], now=time.monotonic):
        self.echo, self.points, self.weights, self.now = echo, points, weights, now
        self.start = now()
        self.done_weight = 0.0
        self.current: str | None = None
        self.suite: str | None = None
        self.last_line = self.start
        self.point_start = self.start
        self._stop = threading.Event()
        self._lock = threading.Lock()
        self._thread = threading.Thread(target=self._beat, name="raybench-progress", daemon=True)
        self._thread.start()

    def _say(self, line: str) -> None:
        with self._lock:
            self.last_line = self.now()
            self.echo(line)

    def left_s(self, i: int) -> float:
        """Seconds the points from i on should take, at the pace of those finished."""
        elapsed = self.now() - self.start
        pace = elapsed / self.done_weight if self.done_weight > 0 else 1.0
        return sum(self.weights[i:]) * pace

    def point(self, i: int, point) -> None:
        if point.suite != self.suite:
            self.suite = point.suite
            count = sum(1 for p in self.points[i:] if p.suite == point.suite)
            self._say(f"suite {point.suite}: {count} point{'s' if count != 1 else ''}")
        self.current, self.point_start = point.describe(), self.now()
        self._say(
            f"[{i + 1}/{len(self.points)}] {self.current}"
            f"  ({clock(self.now() - self.start)} so far, about {clock(self.left_s(i))} left)"
        )

    def done(self, i: int) -> None:
        self.done_weight += self.weights[i]

    def _beat(self) -> None:
        while not self._stop.wait(1.0):
            if self.current is not None and self.now() - self.last_line >= HEARTBEAT_S:
                self._say(f"  still on {self.current}: {clock(self.now() - self.point_start)} on this point")

    def close(self) -> None:
        self._stop.set()
        self._thread.join()
