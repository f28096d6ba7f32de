"""The one exception type raybench raises for input a user can fix."""

import re


class RaybenchError(ValueError):
    """Bad input or an unusable device: the message is one line that says what
    was wrong and what is allowed. The CLI prints it and exits with code 2."""


class Terminated(KeyboardInterrupt):
    """SIGTERM (kill, a job scheduler, a container stopping), raised in the
    main thread as Ctrl-C is (cli.entry sets the handler): every cleanup that
    Ctrl-C runs (a half-made folder removed, a pool of processes closed, the
    points finished kept) runs for it too, and the process ends in one line."""


# The libraries that drive the devices: an exception raised from one of them
# in the middle of a run (a GPU lost, out of memory, a driver reset) is the
# device failing, not raybench's bug, and is told in one line (cli.run).
DEVICE_LIBRARIES = ("numba.cuda", "numba_cuda", "wgpu")


def device_failure(exc: BaseException) -> str | None:
    """One line naming the device's failure, where exc comes from a device
    library (DEVICE_LIBRARIES); else None (any other exception is a bug and
    keeps its traceback)."""
    module = type(exc).__module__ or ""
    if not any(module == lib or module.startswith(lib + ".") for lib in DEVICE_LIBRARIES):
        return None
    text = " ".join(str(exc).split()) or type(exc).__name__
    return f"the device failed ({type(exc).__name__}: {text[:300]})"


def shown(value, limit: int = 60) -> str:
    """value as a message shows it: NumPy scalars and arrays as the plain
    Python numbers and lists they hold (-1.0, not np.float64(-1.0)), cut to
    limit characters so a huge value still makes one short line."""
    tolist = getattr(value, "tolist", None)
    if callable(tolist) and type(value).__module__ == "numpy":
        value = tolist()
    text = " ".join(repr(value).split())
    return text if len(text) <= limit else text[: limit - 3] + "..."


def one_line(text: str) -> str:
    """text with every character that is not printable (a newline, a carriage
    return, a line separator) written as its escape: what the CLI prints is
    then one line, whatever a file name or a hand-edited key holds."""
    text = str(text)
    if text.isprintable():  # (nearly always: checked at C speed, where the escapes go a character at a time)
        return text
    return "".join(c if c.isprintable() else repr(c)[1:-1] for c in text)


# C0 and C1 control characters but tab and newline: what a terminal or a viewer may obey.
_CONTROLS = re.compile(r"[\x00-\x08\x0b-\x1f\x7f-\x9f]")


def controls_shown(text: str) -> str:
    """text with every control character (ESC, NUL, BEL, a carriage return)
    written as its escape, \\x1b: shown, never obeyed. Tabs and newlines stay,
    for the formats (Markdown, HTML) whose own rules deal with them."""
    return _CONTROLS.sub(lambda m: repr(m.group())[1:-1], text)
