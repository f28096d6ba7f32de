"""What the commands print: standard output that cannot be written (a full
disk, /dev/full, a closed pipe) is one line naming it, and a long job's
progress on standard error, shown only once it has run a second."""

from __future__ import annotations

import sys
import time

import click

from ..errors import RaybenchError


def echo(text: str = "") -> None:
    """click.echo, with a failure to write told in one line (exit 2) rather than a traceback."""
    try:
        click.echo(text)
    except OSError as exc:
        raise RaybenchError(f"cannot write to standard output ({exc.strerror or exc})") from None


class Progress:
    """Called with (done, total): from the first second on, "what: done of
    total" on standard error, rewritten in place on a terminal and at most
    once a second elsewhere; end() clears the line it wrote."""

    def __init__(self, what: str, clock=time.monotonic, stream=None):
        self.what, self.clock = what, clock
        self.stream = stream if stream is not None else sys.stderr
        self.start = clock()
        self.shown = -1.0

    def __call__(self, done: int, total: int) -> None:
        now = self.clock()
        if now - self.start < 1.0 or now - self.shown < 1.0:
            return
        self.shown = now
        tty = self.stream.isatty()
        try:
            text = f"{self.what}: {done:,} of {total:,}"
            self.stream.write("\r" + text if tty else text + "\n")
            self.stream.flush()
        except OSError:
            pass  # progress is a courtesy: an unwritable stderr must not stop the work

    def end(self) -> None:
        if self.shown >= 0 and self.stream.isatty():
            try:
                self.stream.write("\r\x1b[K")
                self.stream.flush()
            except OSError:
                pass
