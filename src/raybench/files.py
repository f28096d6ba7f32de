"""Reading inputs with one-line errors, and writing outputs so that nothing
half-written is ever left behind."""

from __future__ import annotations

import os
from pathlib import Path

from .errors import RaybenchError


def read_text(path, what: str) -> str:
    """The UTF-8 text of path; a missing or unreadable file is a one-line
    error naming it as `what` ("scene file", "results file")."""
    path = Path(path)
    try:
        return path.read_text(encoding="utf-8")
    except FileNotFoundError:
        raise RaybenchError(f"{path}: no such {what}") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise RaybenchError(f"{path}: cannot read the {what} ({exc.__class__.__name__}: {exc})") from None


def write_atomic(path, data: bytes) -> None:
    """Write data to path through a temporary file in the same folder and a
    rename, so a reader (or a crash) never sees half a file."""
    path = Path(path)
    folder = path.parent if str(path.parent) else Path(".")
    if not folder.is_dir():
        raise RaybenchError(f"{path}: cannot write: folder {folder} does not exist")
    if path.is_dir():
        raise RaybenchError(f"{path}: cannot write: it is a folder; give a file name")
    tmp = folder / f".{path.name}.{os.getpid()}.tmp"
    try:
        with open(tmp, "wb") as f:
            f.write(data)
        os.replace(tmp, path)
    except OSError as exc:
        try:
            tmp.unlink()
        except OSError:
            pass
        raise RaybenchError(f"{path}: cannot write ({exc.strerror or exc})") from None
