"""Where raybench's compiled kernels are kept between processes, and the
decorators that keep them there: the first picture of a process then loads
machine code instead of compiling it.

Numba's on-disk cache checks only the source file of the function it
compiled, not the files of the functions it calls (kernels/*.py) nor the
constants it read (layout.py): after a change to one of those it would load
stale code. So raybench's cache lives in a folder named after a hash of
every source file of the package and the compiler's version: any change to
raybench starts a new folder. RAYBENCH_CACHE_DIR moves it (default: the
platform's cache folder, cache_dir()).
"""

from __future__ import annotations

import contextlib
import functools
import hashlib
import os
import threading
import types
from pathlib import Path

import filelock
import numba
import platformdirs

ROOT = Path(__file__).parent


def source_hash() -> str:
    """A hash of raybench's source: every .py and .wgsl file of the package."""
    digest = hashlib.sha256()
    for path in sorted([*ROOT.rglob("*.py"), *ROOT.rglob("*.wgsl")]):
        digest.update(path.relative_to(ROOT).as_posix().encode())
        digest.update(path.read_bytes())
    return digest.hexdigest()[:16]


def cache_dir() -> Path:
    """The platform's cache folder for raybench (platformdirs: ~/.cache/raybench or
    $XDG_CACHE_HOME/raybench on Linux, ~/Library/Caches/raybench on macOS,
    %LOCALAPPDATA%\\raybench\\Cache on Windows), one subfolder a source tree."""
    base = os.environ.get("RAYBENCH_CACHE_DIR") or platformdirs.user_cache_dir("raybench", appauthor=False)
    return Path(base) / f"numba-{numba.__version__}-{source_hash()}"


CACHE_DIR = cache_dir()


def _in_cache(decorator):
    """decorator(f), with Numba's cache folder set to CACHE_DIR while it is
    applied: Numba picks a function's cache folder when it is decorated, so
    no other code's cache moves."""

    def decorate(f):
        old = numba.config.CACHE_DIR
        numba.config.CACHE_DIR = str(CACHE_DIR)
        try:
            return _tolerant(decorator(f))
        finally:
            numba.config.CACHE_DIR = old

    return decorate


def _tolerant(dispatcher):
    """The dispatcher, its cache made an optimisation only, and safe for
    several processes at once.

    - Where the machine code cannot be written (a full disk, a quota, ulimit
      -f) Numba raises from inside the first call; then the call goes on with
      the code compiled, and the next process compiles again. (Numba leaves no
      partial file: it writes through a temporary one and removes it on error.)
    - Numba saves a compiled function as two files, an index naming the data
      file of each signature and the data file, one after the other, without
      a lock: two processes compiling two signatures of one function at once
      (a cluster's workers, the tests' processes) can leave an index naming
      for one signature the data file the other wrote, and a later process
      then runs code compiled for other types (numba issue 10128). Each save
      and load holds an exclusive lock on the cache folder's lock file."""
    cache = getattr(dispatcher, "_cache", None)
    save = getattr(cache, "save_overload", None)
    load = getattr(cache, "load_overload", None)
    if save is None or load is None:  # numba's CUDA simulator caches nothing
        return dispatcher

    def save_overload(sig, data):
        try:
            with _locked():
                save(sig, data)
        except OSError:
            pass

    def load_overload(*args, **kwargs):
        with _locked():
            found = load(*args, **kwargs)
        hook = on_compile
        if found is None and hook is not None:  # not in the cache: Numba compiles it now
            hook()
        return found

    cache.save_overload = save_overload
    cache.load_overload = load_overload
    return dispatcher


# Called, with no arguments, each time a function of raybench is not in the
# cache and is about to be compiled (cli.compiling says so on a terminal).
on_compile = None

_held = threading.local()  # how deep this thread is in _locked(): a load within a save, say


@contextlib.contextmanager
def _locked():
    """An exclusive lock on CACHE_DIR/.lock, between processes and threads,
    taken again freely by the thread that holds it (filelock: flock on Unix,
    msvcrt's lock on Windows; where the folder cannot be written, no lock:
    then Numba writes nothing there either)."""
    depth = getattr(_held, "depth", 0)
    if depth:
        _held.depth = depth + 1
        try:
            yield
        finally:
            _held.depth = depth
        return
    try:
        CACHE_DIR.mkdir(parents=True, exist_ok=True)
        # a lock object per taking: two threads' objects exclude each other as two processes' do
        lock = filelock.FileLock(CACHE_DIR / ".lock", thread_local=False)
        try:
            lock.acquire()
        except BaseException:  # Ctrl-C mid-way: leave nothing taken
            with contextlib.suppress(Exception):
                lock.release(force=True)
            raise
    except OSError:
        yield
        return
    try:
        _held.depth = 1
        yield
    finally:
        _held.depth = 0
        lock.release()


def njit(**options):
    """numba.njit(cache=True, **options), cached in CACHE_DIR."""
    return _in_cache(numba.njit(cache=True, **options))


# The CPU walks' leaf tests over a primitive's test (leaf_test): inlined
# where the kind says its test is short (its module's INLINE_TESTS, the
# sphere's), called where it is long. The triangle's watertight test inlined
# at every leaf of the packets, the shadow packets and the 4-wide walk made a
# mesh's Whitted program compile for minutes
# (docs/notes/startup.md#a-kinds-leaf-tests-in-the-packets-called-2026-12-04).
_LEAF_TESTS: set = set()


def leaf_test(**options):
    """numba.njit(inline="always", **options) as the module compiles it (for
    the sphere); rebound's copy for a kind whose INLINE_TESTS is False is a
    function of its own, called, cached and without the runtime's reference
    counting (a leaf test allocates nothing and keeps no array)."""

    def mark(f):
        _LEAF_TESTS.add(f)
        return numba.njit(inline="always", **options)(f)

    return mark


def cuda_jit(**options):
    """numba.cuda.jit(cache=True, **options), cached in CACHE_DIR (numba's
    simulator, which compiles nothing, takes it as a plain cuda.jit)."""
    from numba import cuda

    if numba.config.ENABLE_CUDASIM:
        options.pop("max_registers", None)  # a register budget means nothing there, and its jit refuses one
        return cuda.jit(**options)
    return _in_cache(cuda.jit(cache=True, **options))


def cuda_device(**options):
    """numba.cuda.jit(device=True, **options) (numba's simulator, which
    compiles nothing, takes it without NVVM's forceinline)."""
    from numba import cuda

    if numba.config.ENABLE_CUDASIM:
        options.pop("forceinline", None)
    return cuda.jit(device=True, **options)


def is_ready(name: str) -> bool:
    """Whether mark_ready(name) was said in this cache: the functions it
    names are compiled and saved here."""
    return (CACHE_DIR / "ready" / name).exists()


def mark_ready(name: str) -> None:
    """Say, for later processes, that the functions `name` stands for are
    compiled and saved in this cache (a cache that cannot be written says
    nothing)."""
    try:
        (CACHE_DIR / "ready").mkdir(parents=True, exist_ok=True)
        (CACHE_DIR / "ready" / name).touch()
    except OSError:
        pass


def as_python(module, **plain) -> types.SimpleNamespace:
    """The module's compiled functions as the plain Python they were written
    in, calling one another as plain Python too (a function's globals are the
    namespace, in which each compiled function is replaced by its Python):
    the same algorithm, run by the interpreter, compiling nothing. plain:
    Python for names whose compiled functions call other compiled ones from
    a closure (a primitive's answers, made again with jit = identity)."""
    space = dict(vars(module))
    for name, value in vars(module).items():
        if isinstance(value, numba.core.dispatcher.Dispatcher):
            f = value.py_func
            if f.__module__ != module.__name__:  # written elsewhere (a primitive's rule): its own globals
                space[name] = f
                continue
            space[name] = types.FunctionType(f.__code__, space, f.__name__, f.__defaults__, f.__closure__)
    space.update(plain)
    return types.SimpleNamespace(**space)


def rebound(modules, primitive) -> dict[str, types.SimpleNamespace]:
    """The modules' compiled functions compiled again for another primitive
    (a module of kernels/primitives), each calling the others' copies: the
    cpu's (numba.njit) and cuda's (numba.cuda.jit, kernels and device
    functions alike, each with its own options).

    A module whose program depends on the primitive makes it in `_made`
    (functools.cache'd, its primitive an argument, the sphere by default:
    `_made()` is the module's own program). Each compiled function of the
    modules is copied from its Python over new globals, in which every
    compiled function of the modules is its copy and every part of a
    module's `_made()` (its functions, namespaces of them, dicts of them) is
    the same-named part of the copied `_made(primitive)`. Numba reads a
    function's callees from its globals as it compiles it, so the copies
    compile the very source for the other primitive (a closure's cells are
    swapped as its globals are), and two kinds live in
    one process, neither calling the other's functions. A part the other
    primitive lacks becomes None, so code that calls it fails to compile
    rather than run the sphere's. A leaf test (leaf_test) is copied as a
    called function for a kind whose INLINE_TESTS is False. A module's
    constants that depend on the kind (its `_kind_constants(primitive)`, a
    dict by name: the packets' shape) are the kind's in its copy. Each copy
    is named after its original and the primitive (`_walk_triangle`), in
    its original's module: Numba's cache keys a function by its file, name and code, never by the callees
    in its globals, and names its machine code by module and name, so under
    the original's name a copy would load, or link to, the sphere's code.
    So named, the cpu's copies are cached in CACHE_DIR as the originals are
    (cuda's are compiled in each process). Returns each module's new
    globals, by its last name."""
    kind = primitive.__name__.rsplit(".", 1)[-1]
    swap: dict[int, object] = {}
    # a function's module is its globals' __name__ as it is made (without one, Numba takes it
    # for generated code and caches nothing)
    spaces = {module.__name__: {"__name__": module.__name__} for module in modules}

    cells: list = []  # the copies' closures' cells, their contents swapped by fill() as the globals are

    def copy(f, space):
        closure = None
        if f.__closure__:  # a function a factory made at import (packets.packet_walk's walks)
            closure = tuple(types.CellType(cell.cell_contents) for cell in f.__closure__)
            cells.extend(closure)
        made = types.FunctionType(f.__code__, space, f.__name__, f.__defaults__, closure)
        made.__qualname__ = f"{f.__qualname__}_{kind}"
        return made

    for module in modules:
        space = spaces[module.__name__]
        for value in vars(module).values():
            if id(value) in swap:
                continue
            source, remake = _compiled_source(value)
            if source in _LEAF_TESTS and not primitive.INLINE_TESTS:
                options = {k: v for k, v in value.targetoptions.items() if k not in ("nopython", "inline")}
                remake = njit(**{**options, "nogil": True, "_nrt": False})
            if source is not None and source.__module__ in spaces:
                swap[id(value)] = remake(copy(source, spaces[source.__module__]))
            elif isinstance(value, types.FunctionType) and value.__module__ == module.__name__:
                swap[id(value)] = copy(value, space)
            elif hasattr(value, "cache_clear") and getattr(value, "__module__", None) == module.__name__:
                swap[id(value)] = functools.cache(copy(value.__wrapped__, space))

    def swapped(value):
        if isinstance(value, dict):
            new = {k: swapped(v) for k, v in value.items()}
            return value if all(new[k] is v for k, v in value.items()) else new
        return swap.get(id(value), value)

    def fill():
        for module in modules:
            spaces[module.__name__].update({name: swapped(value) for name, value in vars(module).items()})
        for cell in cells:
            cell.cell_contents = swapped(cell.cell_contents)

    fill()
    for module in modules:
        if hasattr(module, "_made"):
            _pair(module._made(), spaces[module.__name__]["_made"](primitive), swap)
            fill()
    for module in modules:  # its constants that the kind decides (packets' shape)
        if hasattr(module, "_kind_constants"):
            spaces[module.__name__].update(module._kind_constants(primitive))
    return {module.__name__.rsplit(".", 1)[-1]: types.SimpleNamespace(**spaces[module.__name__]) for module in modules}


def per_kind(modules, primitive, home, cached: bool = False) -> dict:
    """Each module's namespace by its last name, for one kind of primitive:
    the modules themselves for `home`, the kind they were compiled for at
    import, else rebound's copies for `primitive`. cached: the copies are in
    the disk cache (the cpu's), whose misses tell on_compile themselves;
    else they compile at their first call, said to on_compile here."""
    if primitive is home:
        return {module.__name__.rsplit(".", 1)[-1]: module for module in modules}
    spaces = rebound(modules, primitive)
    if on_compile is not None and not cached:
        on_compile()
    return spaces


def _compiled_source(value):
    """(the Python a compiled function was made from, how to compile a copy
    of it as it was compiled), or (None, None) for anything else: numba.njit's
    dispatchers, numba-cuda's (kernels and device functions, their options
    kept) and, under numba's CUDA simulator, its stand-ins for them."""
    if isinstance(value, numba.core.dispatcher.Dispatcher):
        options = {k: v for k, v in value.targetoptions.items() if k != "nopython"}
        return value.py_func, njit(**options)  # raybench's: cached
    kind = type(value)
    if kind.__name__ == "CUDADispatcher" and kind.__module__.startswith("numba.cuda"):
        return value.py_func, lambda f: kind(f, targetoptions=dict(value.targetoptions))
    if kind.__name__ == "FakeCUDAKernel" and kind.__module__.startswith("numba.cuda"):
        return value.fn, lambda f: kind(f, value._device, value._fastmath, value.extensions, value._debug)
    return None, None


def _pair(old, new, swap: dict) -> None:
    """swap[id(part)] = the same-named part of `new` (None where it has
    none) for `old` and every function, namespace and dict in it."""
    if isinstance(old, types.SimpleNamespace):
        for name, value in vars(old).items():
            _pair(value, getattr(new, name, None), swap)
    elif isinstance(old, dict):
        for key, value in old.items():
            _pair(value, None if new is None else new.get(key), swap)
    elif not callable(old):
        return
    swap.setdefault(id(old), new)
