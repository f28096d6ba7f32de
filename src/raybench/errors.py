"""The one exception type raybench raises for input a user can fix."""


class RaybenchError(ValueError):
    """Bad input or an unusable device: the message is one line that says what
    was wrong and what is allowed. The CLI prints it and exits with code 2."""


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
    return "".join(c if c.isprintable() else repr(c)[1:-1] for c in str(text))
