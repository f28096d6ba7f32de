"""The Python API checks what a scene file checks, by the same code:
Renderer.update's spheres (scene.check_values), a Scene's camera, a
Shading made for another scene, a cluster's connect timeout and worker count
(backends.limits, which the command line applies too)."""

from __future__ import annotations

import math

import numpy as np
import pytest

import raybench
import raybench.animate
import raybench.cluster
import raybench.kernels.whitted
from raybench import RaybenchError, Scene, lighting
from raybench.backends import limits
from raybench.cli import run
from raybench.layout import BLUE, CX, CZ, RADIUS, RED

# A bad value for a sphere's field, and the row(s) of the (7, n) array it goes in.
FAULTS = [
    ("nan centre", lambda rng: (int(rng.integers(CX, CZ + 1)), np.nan)),
    ("inf centre", lambda rng: (int(rng.integers(CX, CZ + 1)), float(rng.choice([np.inf, -np.inf])))),
    ("far centre", lambda rng: (int(rng.integers(CX, CZ + 1)), float(rng.choice([1, -1]) * 10 ** rng.uniform(16, 38)))),
    ("nan radius", lambda rng: (RADIUS, np.nan)),
    ("negative radius", lambda rng: (RADIUS, -float(rng.uniform(1e-3, 10)))),
    ("zero radius", lambda rng: (RADIUS, 0.0)),
    ("colour above 1", lambda rng: (int(rng.integers(RED, BLUE + 1)), float(rng.uniform(1.001, 100)))),
    ("negative colour", lambda rng: (int(rng.integers(RED, BLUE + 1)), -float(rng.uniform(1e-3, 1)))),
    ("inf colour", lambda rng: (int(rng.integers(RED, BLUE + 1)), np.inf)),
]


def scene_of(spheres: np.ndarray) -> Scene:
    return Scene(spheres[CX : CZ + 1].T, spheres[RADIUS], spheres[RED : BLUE + 1].T)


@pytest.mark.parametrize("fault", [f[0] for f in FAULTS])
def test_update_refuses_what_a_scene_refuses_in_the_same_words(rng, fault):
    """A random scene, one random sphere given a bad value: update() refuses
    it in one line, the very line Scene() gives for the same spheres (the
    one rule), after "update: "; the frames after are the old spheres'."""
    make = dict(FAULTS)[fault]
    scene = raybench.random_spheres(int(rng.integers(2, 40)), seed=int(rng.integers(2**31)))
    with raybench.Renderer(scene, 24, 16, device="cpu") as renderer:
        before = renderer.render().image
        for _ in range(3):
            bad = scene.spheres.copy()
            row, value = make(rng)
            bad[row, int(rng.integers(len(scene)))] = value
            with pytest.raises(RaybenchError) as from_scene:
                scene_of(bad)
            with pytest.raises(RaybenchError) as from_update:
                renderer.update(bad)
            # the same line, the value shown as float32 (the update's) or float64 (the scene's) prints it
            rule, _, got = str(from_update.value).partition(", got ")
            scene_rule, _, scene_got = str(from_scene.value).partition(", got ")
            assert rule == "update: " + scene_rule and "\n" not in got
            np.testing.assert_array_equal(np.float32(eval(got, {"nan": np.nan, "inf": np.inf})),
                                          np.float32(eval(scene_got, {"nan": np.nan, "inf": np.inf})))  # fmt: skip
        np.testing.assert_array_equal(renderer.render().image, before)


def test_a_scene_file_refuses_the_same_values(tmp_path, rng):
    """The finite ones of FAULTS, written in a scene file: refused there too."""
    scene = raybench.random_spheres(5, seed=int(rng.integers(2**31)))
    for _, make in FAULTS:
        row, value = make(rng)
        if not math.isfinite(value):
            continue  # JSON has no NaN or infinity: refused as not a number, the parser's rule
        doc = scene.to_dict()
        field = "center" if row <= CZ else "radius" if row == RADIUS else "color"
        sphere = doc["spheres"][int(rng.integers(5))]
        if field == "radius":
            sphere["radius"] = value
        else:
            sphere[field][row - (CX if field == "center" else RED)] = value
        with pytest.raises(RaybenchError, match=rf"spheres\[\d\]\.{field}: "):
            Scene.from_dict(doc)


def test_update_copies_the_callers_array(rng):
    """The caller changes its array after update(): frames show the spheres
    as they were given, the same frame as a new Renderer of those spheres
    (the tree and the spheres agree); before, the kernel read the changed
    spheres through the tree of the old ones."""
    scene = raybench.random_spheres(int(rng.integers(20, 80)), seed=int(rng.integers(2**31)))
    orbits = raybench.animate.Orbits(scene.spheres, int(rng.integers(1000)))
    given = orbits.at(float(rng.uniform(0.5, 2.0)))
    kept = given.copy()
    with raybench.Renderer(scene, 48, 32, device="cpu") as renderer:
        renderer.update(given)
        given[CX : CZ + 1] += rng.uniform(-3, 3, (3, len(scene))).astype(np.float32)  # moved after the update
        given[RADIUS] *= 3
        frame = renderer.render()
    expected = raybench.render(scene_of(kept), width=48, height=32, device="cpu")
    np.testing.assert_array_equal(frame.image, expected.image)
    np.testing.assert_array_equal(frame.hits, expected.hits)


def test_scene_refuses_a_camera_that_is_not_one():
    for camera in ("x", (0, 0, 0), {"position": [0, 0, 0]}, 1.5):
        with pytest.raises(RaybenchError, match="scene: camera must be a raybench.Camera or None"):
            Scene([[0, 0, 5]], [1], [[1, 1, 1]], camera=camera)


def test_a_shading_of_another_scene_is_refused(rng):
    """Shading.of(a scene of m spheres) given to a Renderer of n != m: one
    line naming both counts (the kernels read its materials unchecked);
    arrays that no Material or Light could make, refused too; one of the
    scene itself, accepted and the same frame as shading="whitted"."""
    n = int(rng.integers(2, 30))
    m = int(rng.choice([k for k in range(1, 40) if k != n]))
    scene = raybench.random_spheres(n, seed=int(rng.integers(2**31)), materials=True)
    other = raybench.random_spheres(m, seed=int(rng.integers(2**31)), materials=True)
    with pytest.raises(RaybenchError, match=rf"shading: made for a scene of {m} spheres, this one has {n}"):
        raybench.Renderer(scene, 8, 6, device="cpu", shading=lighting.Shading.of(other))
    edits = {
        "materials' ior": lambda s: s.materials.__setitem__((raybench.layout.IOR, int(rng.integers(n))), 0.0),
        "materials' reflect + transmit": lambda s: s.materials[
            raybench.layout.REFLECT : raybench.layout.TRANSMIT + 1
        ].__setitem__(slice(None), 0.9),
        "lights in params": lambda s: s.params.__setitem__(raybench.layout.P_LIGHTS, 2),
        "sample points": lambda s: setattr(s, "pattern", np.ascontiguousarray(s.pattern[:, :1])),
        "params must be": lambda s: setattr(s, "params", s.params[:5].copy()),
        "materials must be": lambda s: setattr(s, "materials", s.materials.astype(np.float64)),
        "depth and shadow_samples": lambda s: setattr(s, "depth", 2),
        "lights must be": lambda s: s.lights.__setitem__((raybench.layout.LRADIUS, 0), np.nan),
    }
    for needle, edit in edits.items():
        shading = lighting.Shading.of(scene)
        edit(shading)
        with pytest.raises(RaybenchError, match=needle.replace("+", r"\+")):
            raybench.Renderer(scene, 8, 6, device="cpu", shading=shading)
    with raybench.Renderer(scene, 24, 16, device="cpu", shading=lighting.Shading.of(scene)) as renderer:
        np.testing.assert_array_equal(
            renderer.render().image, raybench.render(scene, width=24, height=16, device="cpu", shading="whitted").image
        )


@pytest.mark.parametrize("value", [math.nan, math.inf, -math.inf, -1.0, 0.0, 0.05, 3600.5, True, "10"])
def test_connect_timeout_is_a_finite_number_in_range(value):
    with pytest.raises(RaybenchError, match="connect timeout: must be a number of seconds from 0.1 to 3600"):
        limits.check_connect_timeout(value)


@pytest.mark.parametrize("value", ["nan", "inf", "-inf", "-1", "0"])
def test_cli_connect_timeout_is_one_line(capsys, monkeypatch, value):
    """nan once reached Dask, which failed with a KeyError."""
    monkeypatch.delenv("RAYBENCH_SCHEDULER", raising=False)
    assert run(["render", "--spheres", "3", "--size", "8x6", "--connect-timeout", value, "--workers", "1"]) == 2
    out, err = capsys.readouterr()
    assert err.count("\n") == 1 and "connect timeout: must be a number of seconds" in err and "Traceback" not in err


def test_workers_have_an_upper_bound_said_in_one_line(capsys, monkeypatch, rng):
    """More workers than max_workers() (WORKERS_PER_CORE a core, and what
    the memory holds at WORKER_BYTES each) is one line naming the bound,
    before any process starts; the bound itself is accepted."""
    monkeypatch.delenv("RAYBENCH_SCHEDULER", raising=False)
    most, why = limits.max_workers()
    assert 1 <= most <= limits.WORKERS_PER_CORE * raybench.host.usable_cores()
    assert limits.check_worker_count(most) == most
    started = []
    monkeypatch.setattr("distributed.SpecCluster.__init__", lambda *a, **k: started.append(1))
    for workers in (most + 1, int(rng.integers(most + 1, 10**6)), 100_000):
        assert run(["render", "--spheres", "3", "--size", "8x6", "--workers", str(workers)]) == 2
        err = capsys.readouterr().err
        assert err.count("\n") == 1 and f"workers: at most {most} on this machine ({why})" in err, err
        with pytest.raises(RaybenchError, match=f"at most {most}"):
            raybench.cluster.Cluster(workers=workers, device="cpu")
    assert started == []


def test_thread_stacks_count_against_an_address_space_limit():
    """Under ulimit -v each thread's stack takes address space: the memory
    check counts the threads the work starts."""
    import resource

    import psutil

    soft, hard = resource.getrlimit(resource.RLIMIT_AS)
    resource.setrlimit(resource.RLIMIT_AS, (psutil.Process().memory_info().vms + 2**30, hard))
    try:
        without, with_16 = raybench.host.host_available_bytes(), raybench.host.host_available_bytes(16)
    finally:
        resource.setrlimit(resource.RLIMIT_AS, (soft, hard))
    stacks = 16 * raybench.host.thread_stack_bytes()
    assert abs((without - with_16) - stacks) < 64 * 2**20, (without, with_16, stacks)


def test_many_threads_under_a_memory_ulimit_are_one_line(tmp_path):
    """A frame that fits a 4 GiB address space, but not with the stacks of
    64 threads: one line and exit 2 (it was "can't start new thread", a
    traceback, once the frame's memory was taken)."""
    import os
    import resource
    import subprocess
    import sys
    from pathlib import Path

    def limit():
        resource.setrlimit(resource.RLIMIT_AS, (4 * 2**30, resource.RLIM_INFINITY))

    out = tmp_path / "x.png"
    proc = subprocess.run(
        [sys.executable, "-m", "raybench", "render", "--spheres", "3", "--size", "16000x16000", "--threads", "64",
         "--device", "cpu", "-o", str(out)],
        preexec_fn=limit, capture_output=True, text=True, timeout=300,
        env=dict(os.environ, PYTHONPATH=str(Path(raybench.__file__).parent.parent)),
    )  # fmt: skip
    assert proc.returncode == 2 and proc.stderr.count("\n") == 1, proc.stderr
    assert "16000x16000 with 3 spheres needs" in proc.stderr and not out.exists()


def test_a_thread_that_cannot_start_is_one_line(capsys, monkeypatch, tmp_path):
    """Wherever a thread is refused (a library's own, or ulimit -u): one line."""
    import sys

    monkeypatch.chdir(tmp_path)

    def refused(*args, **kwargs):
        raise RuntimeError("can't start new thread")

    monkeypatch.setattr(sys.modules["raybench.render"], "render", refused)
    assert run(["render", "--spheres", "3", "--size", "8x6", "--device", "cpu", "-o", "x.png"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "cannot start a thread: out of memory" in err and "Traceback" not in err


# --- the fuzzer, on update() ------------------------------------------------------------

HOSTILE = [np.nan, np.inf, -np.inf, 0.0, -0.0, -1.0, 1e-46, 1.5, 2.0, 1e15, 1.1e15, 1e38, -1e38, 3.4e38]


def test_fuzz_update(tmp_path):
    """Generated sphere arrays for update(): mostly a moved scene, with some
    fields set to hostile values, some arrays of another shape, dtype or
    layout. The property: update() takes exactly what Scene() takes (the one
    rule), in one line otherwise; what it takes renders as a new Renderer of
    that scene renders, even after the caller overwrites its array."""
    from collections import Counter

    from hypothesis import given
    from hypothesis import strategies as st
    from test_fuzz import budget

    seen = Counter()
    base = raybench.random_spheres(12, seed=5)

    @budget(60)
    @given(data=st.data())
    def one(data):
        seen["tried"] += 1
        spheres = base.spheres.copy()
        spheres[CX : CZ + 1] += np.float32(data.draw(st.floats(-2, 2)))
        for _ in range(data.draw(st.integers(0, 3))):
            row, column = data.draw(st.integers(0, 6)), data.draw(st.integers(0, len(base) - 1))
            spheres[row, column] = data.draw(st.sampled_from(HOSTILE))
        kind = data.draw(st.sampled_from(["array"] * 6 + ["float64", "transposed", "short", "list", "strided"]))
        given_array = {
            "array": spheres,
            "float64": spheres.astype(np.float64),
            "transposed": np.asfortranarray(spheres),  # the right shape and dtype, another layout: taken, as C
            "short": spheres[:, :-1],
            "list": spheres.tolist(),
            "strided": np.repeat(spheres, 2, axis=1)[:, ::2],  # a view, not contiguous: taken, as C
        }[kind]
        try:
            expected = scene_of(spheres)  # its own copy: the caller's array is overwritten below
            valid = True
        except RaybenchError:
            valid = False
        with raybench.Renderer(base, 16, 8, device="cpu") as renderer:
            try:
                renderer.update(given_array)
            except RaybenchError as exc:
                assert "\n" not in str(exc) and "np." not in str(exc) and len(str(exc)) < 400, exc
                assert not valid or kind in ("float64", "short", "list"), (kind, exc)
                seen["refused"] += 1
                return
            assert valid and kind in ("array", "transposed", "strided"), kind
            if isinstance(given_array, np.ndarray):
                given_array[...] = 0  # overwritten by the caller after the update
            frame = renderer.render()
        np.testing.assert_array_equal(frame.image, raybench.render(expected, width=16, height=8, device="cpu").image)
        seen["taken"] += 1

    one()
    print(f"update calls: {dict(seen)}")
    assert seen["taken"] >= 0.2 * seen["tried"] and seen["refused"] >= 0.2 * seen["tried"], seen
