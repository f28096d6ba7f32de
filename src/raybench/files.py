"""Reading inputs with one-line errors, and writing outputs so that nothing
half-written is ever left behind.

Every file raybench reads (scenes, results) goes through read_text, and every
JSON document through loads: one place bounds what a file may cost. Every file
it writes goes through write_atomic (Appended, a results file, makes its file
there), which writes regular files only (output_mode).
"""

from __future__ import annotations

import contextlib
import json
import os
import re
import shutil
import signal
import stat
import tempfile
import threading
from pathlib import Path

import numpy as np
import orjson

from .errors import RaybenchError

# Far above a saved scene of 1,000,000 spheres or a results file of every suite
# (their sizes: README.md's limits table). Anything larger is not ours, or not
# a file at all (/dev/zero).
MAX_FILE_BYTES = 512 * 2**20
# A scene nests 3 deep, a results record 5. Far below Python's recursion limit,
# so neither the parser nor anything that walks a document can overflow it.
MAX_JSON_DEPTH = 32


def unix_flags(*names: str) -> int:
    """os.open's flags of these names, those this platform has (Windows has
    no O_NOFOLLOW, O_NONBLOCK or O_CLOEXEC: its files are opened without them)."""
    flags = 0
    for name in names:
        flags |= getattr(os, name, 0)
    return flags


def read_text(path, what: str, max_bytes: int | None = None) -> str:
    """The UTF-8 text of path; a missing or unreadable file, one that is not a
    regular file (a FIFO, a device, a folder), or one over max_bytes is a
    one-line error naming it as `what` ("scene file", "results file")."""
    path = Path(path)
    max_bytes = MAX_FILE_BYTES if max_bytes is None else max_bytes
    try:
        # O_NONBLOCK: opening a FIFO with no writer returns at once instead of
        # waiting; the fstat below then refuses it. (Windows has neither.)
        fd = os.open(path, os.O_RDONLY | unix_flags("O_NONBLOCK") | getattr(os, "O_BINARY", 0))
    except FileNotFoundError:
        raise RaybenchError(f"{path}: no such {what}") from None
    except OSError as exc:
        raise RaybenchError(f"{path}: cannot read the {what} ({exc.strerror or exc})") from None
    try:
        with os.fdopen(fd, "rb") as f:
            info = os.fstat(f.fileno())
            if not stat.S_ISREG(info.st_mode):
                raise RaybenchError(f"{path}: the {what} must be a regular file, not a {file_kind(info.st_mode)}")
            if info.st_size > max_bytes:
                raise RaybenchError(
                    f"{path}: the {what} is {info.st_size / 2**20:,.0f} MiB, over the limit of "
                    f"{max_bytes / 2**20:,.0f} MiB"
                )
            # A file that grows while we read it is still cut at the limit.
            data = f.read(max_bytes + 1)
    except OSError as exc:
        raise RaybenchError(f"{path}: cannot read the {what} ({exc.strerror or exc})") from None
    if len(data) > max_bytes:
        raise RaybenchError(f"{path}: the {what} is over the limit of {max_bytes / 2**20:,.0f} MiB")
    if data.startswith(b"\xef\xbb\xbf"):  # JSON forbids it; the parser's own message would not name it
        raise RaybenchError(
            f"{path}: the {what} starts with a UTF-8 byte-order mark (BOM); save it as UTF-8 without a BOM"
        )
    try:
        return data.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise RaybenchError(f"{path}: cannot read the {what}: not UTF-8 text (byte {exc.start})") from None


def file_kind(mode: int) -> str:
    """What a file that is not a regular one is, in a message: a folder, a pipe, ..."""
    if stat.S_ISDIR(mode):
        return "folder"
    if stat.S_ISFIFO(mode):
        return "pipe"
    if stat.S_ISCHR(mode) or stat.S_ISBLK(mode):
        return "device"
    if stat.S_ISSOCK(mode):
        return "socket"
    return "special file"


class DuplicateKey(RaybenchError):
    """A JSON object names one key twice: json would silently keep the last."""


def _unique_keys(pairs: list) -> dict:
    obj = dict(pairs)
    if len(obj) != len(pairs):
        seen: set = set()
        key = next(k for k, _ in pairs if k in seen or seen.add(k))
        raise DuplicateKey(f"key {json.dumps(key)[:40]} appears twice in one object; keep one")
    return obj


_ESCAPED = re.compile(r"\\.", re.DOTALL)
_STRING = re.compile(r'"[^"]*"')
# Every byte but the brackets and the newline: bytes.translate drops them faster than a regex.
_NOT_BRACKET = bytes(set(range(256)) - set(b"[]{}\n"))
_STEP = np.zeros(256, np.int8)
_STEP[[ord("["), ord("{")]] = 1
_STEP[[ord("]"), ord("}")]] = -1


def json_depth(text: str, lines: bool = False) -> tuple[int, int]:
    """(depth, line): how deeply text's arrays and objects nest, brackets
    inside strings not counted, and the first line (from 1) that nests that
    deep. With lines, each line is a document of its own (JSON Lines) and
    starts again at depth 0. Linear, at C speed, before any parser sees it."""
    # An escaped character (\" among them) says nothing about depth; once they
    # are gone, the quotes of valid JSON pair up and the strings can go. JSON
    # strings hold no raw newline, so the newlines that remain end lines.
    stripped = _STRING.sub("", _ESCAPED.sub("", text))
    kept = stripped.encode("utf-8", "surrogatepass").translate(None, _NOT_BRACKET)
    if not kept:
        return 0, 1
    chars = np.frombuffer(kept, np.uint8)
    levels = np.cumsum(_STEP[chars], dtype=np.int32)
    newline = chars == ord("\n")
    if lines and newline.any():
        # subtract the level each line started at
        starts = np.maximum.accumulate(np.where(newline, np.arange(len(chars)), -1))
        levels = levels - np.where(starts >= 0, levels[np.maximum(starts, 0)], 0)
    deepest = int(np.argmax(levels))
    return int(levels[deepest]), int(newline[:deepest].sum()) + 1


_DECODER = json.JSONDecoder(object_pairs_hook=_unique_keys)


def check_nesting(text: str, where: str, lines: bool = False) -> None:
    """Refuse text nested deeper than MAX_JSON_DEPTH, naming the line."""
    depth, line = json_depth(text, lines)
    if depth > MAX_JSON_DEPTH:
        at = f": line {line}" if lines else ""
        raise RaybenchError(f"{where}{at}: JSON nested {depth} deep, more than the {MAX_JSON_DEPTH} allowed")


# The standard library's parser is the reference: its values, its messages. orjson's is
# taken where it gives the same value, for speed (a results file holds millions of frame
# times). It differs from the reference in three ways, each sent to the reference:
# - an integer past 64 bits becomes a float: any run of 19 digits goes to the reference;
# - a key twice in one object is dropped silently: its value is taken only where it holds
#   every ':' of the text (a key's, or one inside a string; a dropped key takes at least its
#   own), counted in the value written out again. A ':' written as \u003a would count in the
#   value and not in the text, so text holding one goes to the reference;
# - what it refuses and the reference reads (NaN, 1e400, a lone surrogate) it raises on.
_DIGIT_RUNS = bytes(ord("0") if chr(i).isdigit() and i < 128 else ord(" ") for i in range(256))
_ESCAPED_COLON = re.compile(rb"\\u003[aA]")
_REFERENCE = object()


def _fast(text: str):
    """text's value by orjson, or _REFERENCE where only the reference parser can say."""
    try:
        data = text.encode("utf-8")
    except UnicodeEncodeError:  # a lone surrogate in the text itself
        return _REFERENCE
    if b"0" * 19 in data.translate(_DIGIT_RUNS) or (b"\\" in data and _ESCAPED_COLON.search(data)):
        return _REFERENCE
    colons = data.count(b":")
    try:
        value = orjson.loads(data)
        del data  # (a large document's bytes gone before its value is written out again)
        written = orjson.dumps(value).count(b":")
    except (orjson.JSONDecodeError, orjson.JSONEncodeError):
        return _REFERENCE
    return value if written == colons else _REFERENCE


def parse(text: str, where: str):
    """The JSON document text, with no key twice in an object, its depth
    already checked (check_nesting). Any fault is one RaybenchError starting
    with `where` (a file's path, or "path: line N")."""
    value = _fast(text)
    if value is not _REFERENCE:
        return value
    try:
        return _DECODER.decode(text)
    except json.JSONDecodeError as exc:
        raise RaybenchError(f"{where}: not valid JSON: {exc.msg} at line {exc.lineno} column {exc.colno}") from None
    except DuplicateKey as exc:
        raise RaybenchError(f"{where}: {exc}") from None
    except ValueError as exc:  # an integer of more than 4300 digits
        raise RaybenchError(f"{where}: not valid JSON: {exc}".split("\n")[0]) from None
    except RecursionError:  # not reached below MAX_JSON_DEPTH; kept so a future cap cannot bring a traceback
        raise RaybenchError(f"{where}: JSON nested too deeply") from None


def loads(text: str, where: str):
    """The JSON document text, strictly: nesting at most MAX_JSON_DEPTH deep,
    no key twice in an object."""
    check_nesting(text, where)
    return parse(text, where)


def read_json(path, what: str):
    """read_text, then loads: the one way a JSON file is read."""
    return loads(read_text(path, what), str(path))


def _umask() -> int:
    """The process's umask, without changing it (other threads may create files)."""
    try:
        with open("/proc/self/status", encoding="ascii") as f:
            for line in f:
                if line.startswith("Umask:"):
                    return int(line.split()[1], 8)
    except (OSError, ValueError):
        pass
    mask = os.umask(0o022)
    os.umask(mask)
    return mask


def lstat_or_none(path, cannot) -> os.stat_result | None:
    """What is at path, a symlink itself and not its target, or None where
    nothing is; a place that cannot be looked into is refused in one line,
    cannot(why) (why: the system's reason)."""
    try:
        return os.lstat(path)
    except FileNotFoundError:
        return None
    except OSError as exc:
        raise RaybenchError(cannot(exc.strerror or exc)) from None


def output_mode(path, what: str = "") -> int | None:
    """What an output path holds, checked before anything is written there:
    the mode of the regular file there (a write keeps it), or None where there
    is nothing, or a symlink (a write replaces the link, never its target, and
    the new file gets the umask's mode, never the target's). A folder, a FIFO,
    a device or a socket is refused in one line and left as it is; so is a
    name the file system cannot hold (over 255 bytes) or a place that cannot
    be looked into. `what` names the output in the message ("-o", "--gif")."""
    label = f"{what} {path}" if what else str(path)
    info = lstat_or_none(path, lambda why: f"{label}: cannot write there ({why}); choose another path")
    if info is None or stat.S_ISLNK(info.st_mode):
        return None
    if not stat.S_ISREG(info.st_mode):
        raise RaybenchError(
            f"{label}: is a {file_kind(info.st_mode)}, not a regular file; raybench writes regular files only "
            "and leaves this one as it is: choose another path"
        )
    return stat.S_IMODE(info.st_mode)


def check_writable(path, option: str) -> None:
    """Refuse an output path that could not be written, before any time is
    spent on the work: what is there (output_mode), and whether a file can be
    created in its folder, found by creating (and removing) one there:
    permissions as the kernel sees them, read-only file systems included."""
    path = Path(path)
    output_mode(path, option)
    try:
        fd, tmp = tempfile.mkstemp(prefix=".raybench-probe.", dir=path.parent)
    except OSError as exc:
        raise RaybenchError(
            f"{option} {path}: cannot write there ({exc.strerror or exc}); choose another path"
        ) from None
    os.close(fd)
    os.unlink(tmp)


def make_folder(path, option: str) -> Path:
    """The output folder path, made where it is missing (its parent must
    exist); one line where it cannot be (read-only, no permission, a name too
    long, a file in the way)."""
    path = Path(path)
    if not os.path.isdir(path.parent):
        raise RaybenchError(f"{option} {path}: folder {path.parent} does not exist")
    try:
        path.mkdir(exist_ok=True)
    except FileExistsError:
        raise RaybenchError(f"{option} {path}: is a file; give a folder") from None
    except OSError as exc:
        raise RaybenchError(
            f"{option} {path}: cannot make the folder ({exc.strerror or exc}); choose another path"
        ) from None
    if not path.is_dir():  # a link to a file
        raise RaybenchError(f"{option} {path}: is not a folder; give a folder")
    return path


def write_atomic(path, data: bytes, what: str = "") -> None:
    """Write data to path through a temporary file in the same folder and a
    rename, so a reader (or a crash) never sees half a file: the one way
    raybench writes an output.

    Only a regular file is replaced (output_mode): a FIFO, a device or a
    folder at path is refused and left as it is. The temporary file is
    created exclusively under a random name (mkstemp: O_EXCL, no link
    followed), so nothing planted in the folder can redirect the write. A
    regular file that is replaced keeps its mode; a new one, or one written
    where a symlink was, gets the umask's. On any failure (a full disk, an
    interrupt) the temporary file is removed and the old file, if any, is
    left as it was."""
    path = Path(path)
    folder = path.parent
    if not os.path.isdir(folder):
        raise RaybenchError(f"{path}: cannot write: folder {folder} does not exist")
    if os.path.isdir(path):
        raise RaybenchError(f"{path}: cannot write: it is a folder; give a file name")
    mode = output_mode(path, what)
    if mode is None:
        mode = 0o666 & ~_umask()
    with signals_held():
        try:
            # The name is cut so that a long file name still leaves room for the suffix.
            fd, tmp = tempfile.mkstemp(prefix=f".{path.name[:100]}.", suffix=".tmp", dir=folder)
        except OSError as exc:
            raise RaybenchError(f"{path}: cannot write ({exc.strerror or exc})") from None
        try:
            with os.fdopen(fd, "wb") as f:
                f.write(data)
                f.flush()
                if hasattr(os, "fchmod"):  # not on Windows before Python 3.13: chmod by name below
                    os.fchmod(f.fileno(), mode)
                os.fsync(f.fileno())
            if not hasattr(os, "fchmod"):
                os.chmod(tmp, mode)
            output_mode(path, what)  # again, just before the rename: what was planted meanwhile is not replaced
            os.replace(tmp, path)
        except BaseException as exc:
            try:
                os.unlink(tmp)
            except OSError:
                pass
            if isinstance(exc, OSError):
                raise RaybenchError(f"{path}: cannot write ({exc.strerror or exc}); nothing was changed") from None
            raise


class Appended:
    """An output that grows by whole pieces (a results file's records), each
    on disk before append() returns. The first piece makes the file through
    write_atomic, so a failure before it (a full disk) leaves no empty file;
    later pieces are appended to that regular file (a link put in its place
    meanwhile is not followed), and one that fails part way is cut off
    again: the file holds the pieces before it, whole."""

    def __init__(self, path, what: str = ""):
        self.path, self.what = Path(path), what
        self._fd: int | None = None

    def append(self, data: bytes) -> None:
        if self._fd is None:
            if output_mode(self.path, self.what) is None:  # nothing there yet (or a link, replaced)
                write_atomic(self.path, data, self.what)
                self._fd = self._open()
                return
            self._fd = self._open()
        size = os.fstat(self._fd).st_size
        # Ctrl-C and SIGTERM held while a piece is written: one that came as a
        # whole piece was synced (Python raises it as fsync returns) cut it off
        # again, a finished point the file had shown. Now raised once it is on disk.
        with signals_held():
            try:
                view = memoryview(data)
                while view:
                    view = view[os.write(self._fd, view) :]
                os.fsync(self._fd)
            except BaseException:
                with contextlib.suppress(OSError):
                    os.ftruncate(self._fd, size)
                raise

    def _open(self) -> int:
        fd = os.open(self.path, os.O_WRONLY | os.O_APPEND | unix_flags("O_NOFOLLOW", "O_NONBLOCK", "O_CLOEXEC"))
        info = os.fstat(fd)
        if not stat.S_ISREG(info.st_mode):
            os.close(fd)
            label = f"{self.what} {self.path}" if self.what else str(self.path)
            raise RaybenchError(f"{label}: is a {file_kind(info.st_mode)}, not a regular file; choose another path")
        return fd

    def close(self) -> None:
        if self._fd is not None:
            with contextlib.suppress(OSError):
                os.close(self._fd)
            self._fd = None


@contextlib.contextmanager
def folder_atomic(path, replaceable=lambda entry: False):
    """A folder made whole or not at all: yields a new hidden folder beside
    path to fill, which then takes path's place by a rename, so a crash, a
    Ctrl-C or a full disk never leaves a half-made folder under path's name.
    An existing path is replaced only if replaceable(entry) holds for each
    of its entries (what an earlier run of the same writer left); else it is
    refused before anything is made. On any failure the new folder is removed."""
    path = Path(path)
    if path.exists() or path.is_symlink():
        if path.is_symlink() or not path.is_dir():
            raise RaybenchError(f"{path}: is not a folder; choose another output folder")
        foreign = [e.name for e in path.iterdir() if not replaceable(e)]
        if foreign:
            raise RaybenchError(
                f"{path}: holds {shown_name(foreign[0])}{f' and {len(foreign) - 1} more' if len(foreign) > 1 else ''}, "
                "which this would replace; choose a new or empty output folder"
            )
    staged = None
    try:
        # made with the signals held, inside the try that removes it: a
        # SIGTERM or Ctrl-C just after mkdtemp left it behind
        with signals_held():
            try:
                path.parent.mkdir(parents=True, exist_ok=True)
                staged = Path(tempfile.mkdtemp(prefix=f".{path.name[:100]}.", suffix=".partial", dir=path.parent))
            except OSError as exc:
                raise RaybenchError(f"{path}: cannot create the folder ({exc.strerror or exc})") from None
        yield staged
        with signals_held():
            os.chmod(staged, 0o777 & ~_umask())  # mkdtemp's is 0700
            old = None
            if path.exists():
                old = path.with_name(f".{path.name[:100]}.{os.urandom(6).hex()}.old")
                os.rename(path, old)
            os.rename(staged, path)
            if old is not None:
                shutil.rmtree(old, ignore_errors=True)
    except BaseException as exc:
        if staged is None:  # not made: the error is the making's own
            raise
        shutil.rmtree(staged, ignore_errors=True)
        if isinstance(exc, OSError):
            raise RaybenchError(f"{path}: cannot write ({exc.strerror or exc}); nothing was changed") from None
        if isinstance(exc, RaybenchError) and str(staged) in str(exc):  # the name the user gave, not ours
            raise RaybenchError(str(exc).replace(str(staged), str(path))) from None
        raise


def shown_name(name: str) -> str:
    """A file name in a message: quoted as Python writes it, cut to 60 characters."""
    return repr(name[:60])


@contextlib.contextmanager
def signals_held():
    """Ctrl-C (SIGINT), and SIGTERM where Python handles it, held back until
    the block is done, then raised (the first to come): a
    KeyboardInterrupt between mkstemp and the try that removes its file, or
    inside that removal, left a temporary file behind (1 run in about 10 of
    the test of Ctrl-C during a sequence). Only the main thread can set a
    handler, and only there does Python raise KeyboardInterrupt; elsewhere,
    and where the handler is not Python's own, the block runs as it is."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    # SIGINT where Python's own handler raises KeyboardInterrupt; SIGTERM
    # where a Python handler is set (the CLI's raises errors.Terminated)
    saved = {}
    if signal.getsignal(signal.SIGINT) is signal.default_int_handler:
        saved[signal.SIGINT] = signal.default_int_handler
    if callable(signal.getsignal(signal.SIGTERM)):
        saved[signal.SIGTERM] = signal.getsignal(signal.SIGTERM)
    if not saved:
        yield
        return
    held = []
    for signum in saved:
        signal.signal(signum, lambda number, frame: held.append((number, frame)))
    try:
        yield
    finally:
        for signum, handler in saved.items():
            signal.signal(signum, handler)
        if held:  # the signal wins over whatever else the block raised
            number, frame = held[0]
            saved[number](number, frame)
