"""raybench.compiled: the disk cache of compiled code, shared by processes.

Numba writes a function's cache as an index and data files, unlocked: eight
processes compiling eight signatures of one function at once left, in one
round of three tried by hand, an index whose entry for one signature named
another's data file, and the next process to load it ran code compiled for
other types ("can't unbox array", numba issue 10128). raybench's cache
locks each save and load (compiled._locked); with the lock taken out, the
first test failed 2 runs of 2 (an index entry lost)."""

import contextlib
import os
import signal
import subprocess
import sys
import textwrap
import time

import pytest
from conftest import sigint_default

DTYPES = ["float32", "float64", "int32", "int64", "uint8", "int16", "uint16", "int8"]

MODULE = textwrap.dedent(
    """
    from raybench import compiled

    @compiled.njit()
    def weigh(a):
        s = 0.0
        for i in range(a.shape[0]):
            s += a[i] * (i + 1)
        return s
    """
)

ONE = textwrap.dedent(
    """
    import sys, time
    import numpy as np
    import racy
    a = np.arange(1, 40, dtype=sys.argv[1])
    while time.time() < float(sys.argv[2]):
        pass
    racy.weigh(a)
    """
)

CHECK = textwrap.dedent(
    f"""
    import numpy as np
    import racy
    for dtype in {DTYPES!r}:
        a = np.arange(1, 40, dtype=dtype)
        want = float((a.astype(np.float64) * np.arange(1, 40)).sum())
        got = racy.weigh(a)
        assert abs(got - want) <= 1e-3 * want, (dtype, got, want)
    print("ok")
    """
)


def test_processes_compiling_one_function_at_once_leave_a_cache_that_loads_right(tmp_path):
    (tmp_path / "racy.py").write_text(MODULE)
    src = os.path.join(os.path.dirname(os.path.dirname(os.path.abspath(__file__))), "src")
    for round_ in range(2):
        cache = tmp_path / f"cache-{round_}"
        env = {**os.environ, "RAYBENCH_CACHE_DIR": str(cache), "PYTHONPATH": f"{tmp_path}{os.pathsep}{src}"}
        start = time.time() + 3  # all start compiling together, after their imports
        procs = [
            subprocess.Popen([sys.executable, "-c", ONE, dtype, str(start)], env=env, cwd=tmp_path) for dtype in DTYPES
        ]
        assert [p.wait(timeout=300) for p in procs] == [0] * len(DTYPES)
        assert len(list(cache.rglob("*.nbc"))) == len(DTYPES)  # every signature saved, none lost
        check = subprocess.run(
            [sys.executable, "-c", CHECK], env=env, cwd=tmp_path, capture_output=True, text=True, timeout=600
        )
        assert check.returncode == 0 and check.stdout.strip() == "ok", check.stderr[-2000:]


WHITTED_ONE = textwrap.dedent(
    """
    import sys
    import raybench
    scene = raybench.random_spheres(30, seed=1, materials=True)
    raybench.render(scene, None, 16, 8, device="cpu", shading="whitted", accel=sys.argv[1])
    """
)

WHITTED_BOTH = textwrap.dedent(
    """
    import sys
    import numpy as np
    import raybench
    scene = raybench.random_spheres(int(sys.argv[1]), seed=int(sys.argv[2]), materials=True)
    frames = [raybench.render(scene, None, 48, 32, device="cpu", shading="whitted", accel=accel, threads=1)
              for accel in ("bvh", "none")]
    assert frames[0].rays == frames[1].rays and frames[0].rays["reflection"] > 0, [f.rays for f in frames]
    assert np.array_equal(frames[0].hits, frames[1].hits) and np.array_equal(frames[0].image, frames[1].image)
    print("ok")
    """
)


@pytest.mark.slow
def test_whitted_kernels_cached_by_different_processes_load_together(tmp_path, rng):
    """Whitted's kernel through the tree and by brute force, each compiled
    into the cache by a process of its own, then both loaded by one process:
    each calls its own search. Their searches were once one symbol name in
    both (Numba names a function by its qualified name and a per-process
    counter): brute force's kernel, loaded second, called the tree's walk on
    a tree of no nodes, and the process died of a segfault."""
    src = os.path.join(os.path.dirname(os.path.dirname(os.path.abspath(__file__))), "src")
    env = {**os.environ, "RAYBENCH_CACHE_DIR": str(tmp_path / "cache"), "PYTHONPATH": src}
    procs = [subprocess.Popen([sys.executable, "-c", WHITTED_ONE, accel], env=env) for accel in ("bvh", "none")]
    assert [p.wait(timeout=600) for p in procs] == [0, 0]
    args = [str(int(rng.integers(20, 200))), str(int(rng.integers(2**31)))]
    both = subprocess.run(
        [sys.executable, "-c", WHITTED_BOTH, *args], env=env, capture_output=True, text=True, timeout=600
    )  # fmt: skip
    assert both.returncode == 0 and both.stdout.strip() == "ok", (both.returncode, both.stderr[-2000:])


def test_the_cache_lock_is_taken_again_by_its_thread(tmp_path, monkeypatch):
    """A load within a save (or any nesting in one thread) must not wait for itself."""
    from raybench import compiled

    monkeypatch.setattr(compiled, "CACHE_DIR", tmp_path)
    with compiled._locked(), compiled._locked():
        assert (tmp_path / ".lock").exists()


@pytest.mark.slow
def test_a_first_picture_does_not_wait_for_the_builders_compile(tmp_path, rng):
    """`raybench render` with an empty cache: the tree is built by the
    builder's Python while a child compiles it into the cache; the process
    waits for the child (the cache then holds the builder), and the next
    process builds with the compiled builder the same picture."""
    src = os.path.join(os.path.dirname(os.path.dirname(os.path.abspath(__file__))), "src")
    env = {**os.environ, "RAYBENCH_CACHE_DIR": str(tmp_path / "cache"), "PYTHONPATH": src}
    spheres, seed = str(int(rng.integers(50, 800))), str(int(rng.integers(2**31)))
    runs = []
    for name in ("cold.png", "warm.png"):
        args = ["render", "--device", "cpu", "--spheres", spheres, "--seed", seed, "--size", "96x64", "-o", name]
        command = [sys.executable, "-m", "raybench", *args]
        proc = subprocess.run(command, env=env, cwd=tmp_path, capture_output=True, text=True, timeout=600)
        assert proc.returncode == 0, proc.stderr[-2000:]
        runs.append(proc.stdout)
        ready = list((tmp_path / "cache").glob("*/ready/builder"))
        assert len(ready) == 1, list((tmp_path / "cache").rglob("*"))  # the child finished before the process ended
    assert "as it compiles for later runs" in runs[0] and "Python" not in runs[1], runs
    assert (tmp_path / "cold.png").read_bytes() == (tmp_path / "warm.png").read_bytes()


def compiling(proc) -> list:
    """The builder's compiling child of proc, once it runs its own program.
    Python starts a child with vfork, where the parent waits in the kernel
    until the child has called exec: a child held stopped before that holds
    its parent with it, beyond the reach of Ctrl-C (a loaded machine once
    caught one there)."""
    import psutil

    try:
        return [c for c in psutil.Process(proc.pid).children() if "-c" in c.cmdline()]
    except psutil.Error:
        return []


@pytest.mark.slow
@pytest.mark.parametrize("when", ["before the picture", "after the picture"])
def test_ctrl_c_with_the_builders_compile_under_way_ends_the_process(tmp_path, when):
    """Ctrl-C (SIGINT to the process group, as a terminal sends it) while the
    child that compiles the builder cannot act on it (held stopped): the process
    ends, with no traceback, and the child is stopped.

    Before the picture is written (the frame kernel compiling): one line,
    'interrupted', exit 130, no picture. Without stopping the child there, the
    process hung at exit waiting for it. After the picture: the picture kept,
    and the signal lands either in the wait for the child at exit (quiet) or
    just before it (one line); CI's loaded machine once found the second."""
    import psutil

    src = os.path.join(os.path.dirname(os.path.dirname(os.path.abspath(__file__))), "src")
    env = {**os.environ, "RAYBENCH_CACHE_DIR": str(tmp_path / "cache"), "PYTHONPATH": src}
    args = ["render", "--device", "cpu", "--spheres", "300", "--size", "64x48", "-o", "x.png"]
    proc = subprocess.Popen(
        [sys.executable, "-m", "raybench", *args], env=env, cwd=tmp_path, text=True,
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, start_new_session=True, preexec_fn=sigint_default,
    )  # fmt: skip
    children = []
    try:
        deadline = time.monotonic() + 120
        while not (children := compiling(proc)) and time.monotonic() < deadline:
            time.sleep(0.01)
        assert children, "no child was started"
        for child in children:
            child.suspend()
        if when == "after the picture":
            said = proc.stdout.readline()  # the picture is written; the process heads for its exit
            assert "as it compiles for later runs" in said, said
        os.killpg(proc.pid, signal.SIGINT)
        out, err = proc.communicate(timeout=120)
    finally:
        for process in (proc, *children):  # nothing left behind, whatever failed
            with contextlib.suppress(psutil.Error, OSError):
                process.kill()
    assert "Traceback" not in err, err
    if when == "after the picture":
        assert err.strip() in ("", "raybench: interrupted"), err
        assert (tmp_path / "x.png").stat().st_size > 0
    else:
        # the frame kernel's compile takes seconds on a fresh cache: the signal lands in it
        assert err.strip() == "raybench: interrupted" and proc.returncode == 130, (proc.returncode, out, err)
        assert not (tmp_path / "x.png").exists()
    # a kill is delivered, not awaited: the children are given a deadline to be gone (CI once
    # caught one still listed an instant after its SIGKILL)
    deadline = time.monotonic() + 10
    while (alive := [c for c in children if _running(c, psutil)]) and time.monotonic() < deadline:
        time.sleep(0.05)
    assert not alive, alive


def _running(process, psutil) -> bool:
    """Whether the process is still there and not a zombie."""
    try:
        return process.is_running() and process.status() != psutil.STATUS_ZOMBIE
    except psutil.Error:
        return False


def _sum_of_squares(a):
    s = 0.0
    for x in a:
        s += x * x
    return s


def test_a_cache_miss_is_announced_and_a_hit_is_not(tmp_path, monkeypatch):
    """compiled.on_compile is called before Numba compiles (the function is not in
    the cache) and not when a later dispatcher loads it from there."""
    import io

    import numpy as np
    from rich.console import Console

    from raybench import compiled
    from raybench.cli import compiling

    monkeypatch.setattr(compiled, "CACHE_DIR", tmp_path)
    out = io.StringIO()
    console = Console(file=out, force_terminal=True)
    a = np.random.default_rng().uniform(size=7)
    with compiling.announced(console):
        assert compiled.njit()(_sum_of_squares)(a) == pytest.approx(float((a * a).sum()))
    assert compiling.MESSAGE in out.getvalue() and compiled.on_compile is None
    out.truncate(0)
    calls = []
    monkeypatch.setattr(compiled, "on_compile", lambda: calls.append(1))
    assert compiled.njit()(_sum_of_squares)(a) == pytest.approx(float((a * a).sum()))  # from the cache
    assert calls == []


def test_piped_stderr_stays_clean(monkeypatch, capsys):
    from raybench import compiled
    from raybench.cli import compiling

    monkeypatch.setattr("sys.stderr.isatty", lambda: False)
    with compiling.announced():
        assert compiled.on_compile is None  # nothing listens, nothing is shown
    assert capsys.readouterr().err == ""


def test_rebound_copies_call_no_original_kernel():
    """compiled.rebound's copies for the triangle reach none of the sphere's
    compiled functions, through their globals or a closure's cells (a walk a
    factory made at import, packets.packet_walk's): every callee a copy
    names is itself a copy, so no triangle frame runs a sphere's leaf test.
    kernels/footprint.py's and kernels/packet_boxes.py's functions, which
    know no primitive, are shared, and so are triangle_mesh.py's reads of a
    mesh through the tree's order (kernels/tree_leaves.py), which know the
    triangle alone, whatever kind the modules are copied for."""
    import numba

    from raybench import compiled
    from raybench.backends.cpu import kinds
    from raybench.kernels import footprint, packet_boxes
    from raybench.kernels.primitives import triangle, triangle_mesh

    shared = (footprint.__name__, packet_boxes.__name__, triangle_mesh.__name__)
    originals = {
        id(value)
        for module in kinds.MODULES
        for value in vars(module).values()
        if isinstance(value, numba.core.dispatcher.Dispatcher) and value.py_func.__module__ not in shared
    }
    spaces = compiled.rebound(kinds.MODULES, triangle)
    checked = 0
    for space in spaces.values():
        for name, value in vars(space).items():
            if not isinstance(value, numba.core.dispatcher.Dispatcher) or id(value) in originals:
                continue
            f = value.py_func
            reached = [f.__globals__.get(n) for n in f.__code__.co_names]
            reached += [cell.cell_contents for cell in f.__closure__ or ()]
            stale = [getattr(r, "__name__", r) for r in reached if id(r) in originals]
            assert not stale, f"{name} still calls the sphere's {stale}"
            checked += 1
    assert checked > 20  # the modules' kernels were copied at all


def test_a_kinds_long_test_is_called_at_the_cpus_leaves_and_a_short_one_inlined():
    """compiled.leaf_test: the walks' leaf tests over the sphere's test are inlined
    (sphere.INLINE_TESTS), and rebound's copies for the triangle are functions
    of their own, called, without the runtime's reference counting."""
    from raybench import compiled
    from raybench.backends.cpu import kinds
    from raybench.kernels import packets, shadow_packets, wide_walk
    from raybench.kernels.primitives import sphere, triangle

    assert sphere.INLINE_TESTS and not triangle.INLINE_TESTS
    spaces = compiled.rebound(kinds.MODULES, triangle)
    for module, name in ((packets, "_packet_rays"), (shadow_packets, "_lanes_hit"), (wide_walk, "_wide_leaf")):
        assert getattr(module, name).targetoptions["inline"] == "always"
        copy = getattr(spaces[module.__name__.rsplit(".", 1)[-1]], name)
        assert "inline" not in copy.targetoptions and copy.targetoptions["_nrt"] is False, copy.targetoptions
        assert copy.py_func.__qualname__ == f"{name}_triangle"


def test_a_kinds_copy_tiles_by_its_own_packets(rng):
    """A kind's packet shape (PACKET_SHAPE) and footprint rule
    (PACKET_FOOTPRINT) are its copy's: the packets' and Whitted's rows'
    copies for a kind of another shape (the triangle's module with 8x4
    packets) read its width, height, size and middle ray, the sphere's
    modules keep theirs; a shape whose height does not divide the sphere's
    (the rows a band of the frame starts on) is refused before anything
    compiles."""
    from types import ModuleType, SimpleNamespace

    from raybench import compiled
    from raybench.backends.cpu import kinds
    from raybench.kernels import packets
    from raybench.kernels.primitives import sphere, triangle

    other = ModuleType("triangle_8x4")
    other.__dict__.update(vars(triangle))
    other.PACKET_SHAPE = (8, 4)
    spaces = compiled.rebound(kinds.MODULES, other)
    width, height = other.PACKET_SHAPE
    assert (width, height) != sphere.PACKET_SHAPE
    for name in ("packets", "whitted_rows"):
        space = spaces[name]
        assert (space.PACKET_W, space.PACKET_H, space.PACKET) == (width, height, width * height), name
    assert spaces["packets"]._MIDDLE == (height // 2) * width + width // 2
    assert spaces["packets"].FOOTPRINT is True and compiled.rebound(kinds.MODULES, triangle)["packets"].FOOTPRINT
    assert (packets.PACKET_W, packets.PACKET_H) == sphere.PACKET_SHAPE and packets.FOOTPRINT is False
    odd = int(rng.choice([3, 5, 6, 7]))
    with pytest.raises(ValueError, match="must divide"):
        packets._kind_constants(SimpleNamespace(PACKET_SHAPE=(8, odd)))
