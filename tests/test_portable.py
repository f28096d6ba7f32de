"""raybench beyond Linux: with the Unix-only pieces it used hidden (the
resource and fcntl modules, os.O_NONBLOCK, os.fchmod, os.sched_getaffinity),
as on Windows, `import raybench` works, and the command line reads a scene,
renders it on the CPU and writes the PNG: the picture of a normal process,
pixel for pixel. Third-party libraries (psutil, numba) are loaded first: they
bring their own code for each platform, and are not what is tested here."""

import os
import subprocess
import sys

import numpy as np
import pytest
from PIL import Image

import raybench
from raybench import files, host

CHILD = """
import os, sys
import numba, numpy, psutil, PIL.Image, click, rich, filelock, platformdirs  # noqa: their own platform code
for name in ("resource", "fcntl"):
    sys.modules[name] = None  # import raises ImportError, as where there is none
for name in ("O_NONBLOCK", "fchmod", "sched_getaffinity"):
    if hasattr(os, name):
        delattr(os, name)
import raybench
import raybench.bench.report, raybench.bench.runner, raybench.bench.compare, raybench.backends.wgpu  # noqa
from raybench.cli import run
sys.exit(run(["render", "--scene", sys.argv[1], "--size", "48x32", "--device", "cpu", "-o", sys.argv[2]]))
"""


@pytest.mark.slow  # the child loads (or compiles) the CPU kernels: 5-25 s on 2 cores
def test_import_and_render_with_the_unix_only_modules_hidden(tmp_path, rng):
    scene = raybench.random_spheres(30, seed=int(rng.integers(1 << 31)))
    scene.save(tmp_path / "scene.json")
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(os.path.dirname(raybench.__path__[0])), *sys.path])}
    done = subprocess.run(
        [sys.executable, "-c", CHILD, str(tmp_path / "scene.json"), str(tmp_path / "out.png")],
        env=env,
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert done.returncode == 0, done.stderr[-3000:]
    assert "Traceback" not in done.stderr
    expected = raybench.render(raybench.Scene.load(tmp_path / "scene.json"), width=48, height=32, device="cpu")
    assert np.array_equal(np.asarray(Image.open(tmp_path / "out.png").convert("RGB")), expected.image)


def test_memory_headroom_without_resource(monkeypatch):
    """No ulimits to read: the free memory and the cgroup's limit still bound it."""
    monkeypatch.setattr(host, "resource", None)
    got = host.host_available_bytes()
    assert 0 < got <= host.psutil.virtual_memory().total


def test_reading_and_writing_without_o_nonblock_and_fchmod(monkeypatch, tmp_path):
    monkeypatch.delattr(os, "O_NONBLOCK")
    monkeypatch.delattr(os, "fchmod")
    target = tmp_path / "out.bin"
    target.write_bytes(b"old")
    target.chmod(0o640)
    files.write_atomic(target, b"new")
    assert target.read_bytes() == b"new" and (target.stat().st_mode & 0o777) == 0o640  # the mode kept
    assert files.read_text(target, "file") == "new"
