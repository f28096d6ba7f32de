"""The one exception type raybench raises for input a user can fix."""


class RaybenchError(ValueError):
    """Bad input or an unusable device: the message is one line that says what
    was wrong and what is allowed. The CLI prints it and exits with code 2."""
