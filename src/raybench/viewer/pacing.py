"""Frame pacing and frame statistics, free of threads and windows.

Handoff is the pacing rule between the tracing thread and the window: one
frame is traced while the previous one is on screen. At most one frame is in
flight and at most one waits to be shown, so frames never queue up behind a
slow device (input is always applied to the very next frame), no traced frame
is thrown away, and a fast device is not held back by drawing: tracing frame
k + 1 overlaps showing frame k.

FrameStats turns the frames shown into the overlay's numbers: the frame time
(what tracing took, averaged over the last second), frames per second, and
rays per second (the rays the frames cast over the time tracing them).
"""

from __future__ import annotations

import threading
from collections import deque

WINDOW_S = 1.0


class Handoff:
    """The two slots between the tracer thread and the window; thread-safe."""

    def __init__(self):
        self._lock = threading.Lock()
        self._in_flight = None
        self._ready = None

    def may_trace(self) -> bool:
        """True when nothing is being traced and nothing waits to be shown."""
        with self._lock:
            return self._in_flight is None and self._ready is None

    def start(self, request) -> None:
        with self._lock:
            if self._in_flight is not None or self._ready is not None:
                raise RuntimeError("a frame is already in flight or waiting to be shown")
            self._in_flight = request

    def finish(self, result) -> None:
        """The tracer thread is done with the frame in flight."""
        with self._lock:
            self._in_flight = None
            self._ready = result

    def take(self):
        """The finished frame, for the window to show (None if there is none yet)."""
        with self._lock:
            result, self._ready = self._ready, None
            return result

    @property
    def in_flight(self):
        with self._lock:
            return self._in_flight


class FrameStats:
    """Frames shown in the last second: when each was shown, and how long it took to trace."""

    def __init__(self, window_s: float = WINDOW_S):
        self.window_s = window_s
        self._frames: deque[tuple[float, float, int]] = deque()  # (shown at, trace ms, rays cast)
        self._last: tuple[float, float, int] | None = None
        self._interval: float | None = None  # seconds between the last two frames shown

    def add(self, shown_at: float, trace_ms: float, rays: int = 0) -> None:
        if self._last is not None:
            self._interval = shown_at - self._last[0]
        self._last = (shown_at, trace_ms, rays)
        self._frames.append(self._last)

    def reset(self) -> None:
        """Start afresh (a new device or size: old numbers would mislead)."""
        self.__init__(self.window_s)

    def _recent(self, now: float) -> list[tuple[float, float, int]]:
        while self._frames and self._frames[0][0] <= now - self.window_s:
            self._frames.popleft()
        return list(self._frames)

    def frame_ms(self, now: float) -> float | None:
        """Mean trace time of the frames shown in the last second; when frames
        take longer than that, the last frame's."""
        recent = self._recent(now)
        if recent:
            return sum(ms for _, ms, _ in recent) / len(recent)
        return None if self._last is None else self._last[1]

    def rays_per_s(self, now: float) -> float | None:
        """Rays cast per second of tracing by the frames shown in the last
        second (all their rays over all their trace time); when frames take
        longer than that, the last frame's."""
        frames = self._recent(now) or ([self._last] if self._last is not None else [])
        ms = sum(ms for _, ms, _ in frames)
        return sum(rays for _, _, rays in frames) / ms * 1e3 if ms > 0 else None

    def fps(self, now: float) -> float | None:
        """Frames shown per second over the last second; when frames come less
        often than that, 1 / the time between the last two (and never more
        than the time waited since the last one allows)."""
        recent = self._recent(now)
        if len(recent) >= 2:
            return (len(recent) - 1) / (recent[-1][0] - recent[0][0]) if recent[-1][0] > recent[0][0] else None
        if self._interval is None or self._interval <= 0:
            return None
        return 1.0 / max(self._interval, now - self._last[0])
