"""The one-shot picture's tree, in Python.

A process that makes one picture (raybench.render, `raybench render`) of a
scene of at most sah.WIDE spheres may build its tree with the builder's own
code run as plain Python (compiled.as_python): the same tree, bit for bit,
in a fraction of a second, where compiling the builder takes many seconds
(the figures: docs/notes/startup.md#a-one-shot-pictures-tree-built-by-the-builders-python).
It does so where that is quicker:
- the builder is not yet in the compile cache. A child process compiles it
  into the cache meanwhile, beside the frame kernel's compile, and the
  process waits for the child before it exits, leaving nothing running;
- the picture is traced on a GPU (cuda, wgpu) and the scene has at most
  GPU_PYTHON_MAX spheres: the compiled builder, even cached, needs Numba's
  CPU compiler started (its registries, and SciPy where it is installed),
  which nothing else of such a process needs and which costs more than
  Python's build of so few spheres.
Objects that keep a scene for many frames (Renderer, the bench, the viewer)
build with the compiled builder: their build times are compiled code's.
"""

from __future__ import annotations

import atexit
import contextlib
import subprocess
import sys
import threading
from pathlib import Path

from .. import compiled

READY = "builder"  # compiled.mark_ready's name for the one-thread way
GPU_PYTHON_MAX = 2048
_one_shot = threading.local()
_child: subprocess.Popen | None = None
_CHILD_LOCK = threading.Lock()
# the child compiles this very package: the folder it is in goes first on its path
_CHILD = "import sys; sys.path.insert(0, sys.argv[1]); from raybench.bvh import sah; sah.compile_builder(wide=False)"


@contextlib.contextmanager
def one_shot():
    """Within: a build of at most sah.WIDE spheres may run the builder as plain
    Python (above), and a build's way is told by last_build_in_python()."""
    before = getattr(_one_shot, "on", False)
    _one_shot.on = True
    try:
        yield
    finally:
        _one_shot.on = before


def active() -> bool:
    """Whether this thread is within one_shot()."""
    return getattr(_one_shot, "on", False)


def note_build(interpreted: bool) -> None:
    """Record the way of this thread's last build, for last_build_in_python()."""
    _one_shot.python = interpreted


def last_build_in_python() -> bool:
    """Whether this thread's last build within one_shot() ran the builder as Python."""
    return getattr(_one_shot, "python", False)


def compiling_elsewhere() -> bool:
    """Whether this process started the child that compiles the builder."""
    return _child is not None


def in_python(n: int, wide: int, device: str) -> tuple[bool, bool]:
    """(whether to build in Python, whether to compile the builder elsewhere meanwhile)."""
    if not active() or n > wide:
        return False, False
    if device != "cpu" and n <= GPU_PYTHON_MAX:
        return True, False
    missing = not compiled.is_ready(READY)
    return missing, missing


def compile_elsewhere() -> None:
    """Start the child that compiles the one-thread way into the cache, once
    a process; the process waits for it at exit (wait_for_compiling_elsewhere)."""
    global _child
    with _CHILD_LOCK:
        if _child is None:
            _child = _start_child()
            if _child is not None:
                atexit.register(wait_for_compiling_elsewhere)


def wait_for_compiling_elsewhere() -> None:
    """Wait for the child's compile, if one was started. Ctrl-C meanwhile (the
    picture is written by then) stops the child and ends the wait without a
    traceback; the next process compiles the builder. The CLI calls this before
    it exits, where it catches Ctrl-C itself; at exit it runs again, for scripts."""
    if _child is None:
        return
    try:
        _child.wait()
    except KeyboardInterrupt:
        stop_compiling_elsewhere()


def stop_compiling_elsewhere() -> None:
    """Stop the child that compiles the builder, if one runs: Ctrl-C before
    the process reached its wait. A terminal's Ctrl-C reaches the child too, but
    a child that cannot act on it (held stopped, or the signal sent to this
    process alone) would hold the wait for as long as it compiles."""
    if _child is not None:
        _child.kill()  # a child already ended is not signalled (Popen.send_signal polls first)
        _child.wait()


def _start_child() -> subprocess.Popen | None:
    try:
        return subprocess.Popen(
            [sys.executable, "-c", _CHILD, str(Path(__file__).resolve().parents[2])],
            stdin=subprocess.DEVNULL,
            stdout=subprocess.DEVNULL,
            stderr=subprocess.DEVNULL,
        )
    except OSError:
        return None  # no child: the next process compiles, or runs uncompiled again
