"""On a terminal, say so while this process compiles kernels: the first run on
a machine spends seconds in Numba's compiler (docs/notes/startup.md#where-it-stands),
which would otherwise look like a hang. Piped, stderr stays clean."""

from __future__ import annotations

import contextlib
import sys
import threading

from .. import compiled

# Numba's compiler (LLVM) runs to its end before Python sees a Ctrl-C: said plainly, so that
# a Ctrl-C that waits is not taken for a hang (docs/notes/faults.md#where-it-stands).
MESSAGE = "compiling kernels for this machine, first run only (Ctrl-C waits for it)"
# A kind of primitive other than the sphere: its own copies of the kernels (backends/cpu/kinds.py,
# backends/cuda/kinds.py; the cpu's are cached, cuda's compile in each process).
KIND_MESSAGE = "compiling the kernels for triangles (Ctrl-C waits for it)"


@contextlib.contextmanager
def announced(console=None, message: str = MESSAGE):
    """While the block runs, a spinner with the message on stderr from the
    first cache miss (compiled.on_compile) until the block ends; nothing when
    stderr is no terminal (console: rich's, for the tests)."""
    if console is None:
        if not sys.stderr.isatty():
            yield
            return
        from rich.console import Console

        console = Console(stderr=True)
    status = None
    lock = threading.Lock()

    def start():
        nonlocal status
        with lock:
            if status is None:
                status = console.status(message)
                status.start()

    compiled.on_compile = start
    try:
        yield
    finally:
        compiled.on_compile = None
        with lock:
            if status is not None:
                status.stop()
