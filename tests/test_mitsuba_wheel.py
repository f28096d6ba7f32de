"""`benchmarks/lease_wheels.sh mitsuba` on small wheels of Mitsuba's and Dr.Jit's shape: what it keeps and
drops, a RECORD that lists every file left with its hash and size (checked here with hashlib), the
variants config.py names, and its refusals. peers.py mitsuba's refusals of bad flags, without
Mitsuba."""

import base64
import hashlib
import os
import subprocess
import sys
import zipfile
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
SCRIPT = ROOT / "benchmarks" / "lease_wheels.sh"
TAG = "cp312-cp312-manylinux_2_28_x86_64"
VARIANTS = ["scalar_rgb", "llvm_ad_rgb", "cuda_ad_rgb", "cuda_ad_spectral"]
MITSUBA_FILES = [
    "mitsuba/__init__.py",
    "mitsuba/__init__.pyi",
    "mitsuba/libmitsuba.so",
    "mitsuba/libembree3.so",
    "mitsuba/mitsuba_ext.cpython-312-x86_64-linux-gnu.so",
    "mitsuba/python/util.py",
    "mitsuba/data/srgb.coeff",
    "mitsuba/include/mitsuba/mitsuba.h",
    "mitsuba/plugins/ply.so",
    "mitsuba/plugins/merge.so",
    "mitsuba/plugins/sphere.so",
    "mitsuba/plugins/aov.so",
    *(f"mitsuba/{v}.cpython-312-x86_64-linux-gnu.so" for v in VARIANTS),
    "mitsuba-3.9.1.dist-info/METADATA",
    "mitsuba-3.9.1.dist-info/WHEEL",
]
DRJIT_FILES = ["drjit/__init__.py", "drjit/__init__.pyi", "drjit/libdrjit-core.so", "drjit/include/drjit/jit.h",
               "drjit/cmake/drjit/drjitConfig.cmake", "drjit-1.5.0.dist-info/METADATA"]  # fmt: skip


def wheel(path: Path, files: list[str], extra: dict | None = None) -> None:
    """A wheel whose every file's bytes are its own name (config.py: Mitsuba's variant list)."""
    record = f"{path.name.split('-')[0]}-{path.name.split('-')[1]}.dist-info/RECORD"
    with zipfile.ZipFile(path, "w") as z:
        for name in files:
            z.writestr(name, (extra or {}).get(name, name.encode()))
        z.writestr(record, "stale RECORD\n")


def run(folder: Path, out: Path, **env) -> subprocess.CompletedProcess:
    return subprocess.run(["bash", str(SCRIPT), "mitsuba", str(folder)], capture_output=True, text=True,
                          env={**os.environ, "MI_OUT": str(out), **env})  # fmt: skip


@pytest.fixture
def wheels(tmp_path):
    folder = tmp_path / "in"
    folder.mkdir()
    config = f"PYTHON = 'x'\nMI_VARIANTS = {VARIANTS!r}\nOTHER = 1\n".encode()
    wheel(folder / f"mitsuba-3.9.1-{TAG}.whl", [*MITSUBA_FILES, "mitsuba/config.py"], {"mitsuba/config.py": config})
    wheel(folder / f"drjit-1.5.0-{TAG}.whl", DRJIT_FILES)
    wheel(folder / "trimesh-4.12.2-py3-none-any.whl", ["trimesh/__init__.py"])
    return folder


def listed(path: Path) -> tuple[dict, zipfile.ZipFile]:
    z = zipfile.ZipFile(path)
    record = next(n for n in z.namelist() if n.endswith(".dist-info/RECORD"))
    rows = dict(line.split(",", 1) for line in z.read(record).decode().splitlines())
    assert rows.pop(record) == ","
    for name, row in rows.items():
        digest = base64.urlsafe_b64encode(hashlib.sha256(z.read(name)).digest()).rstrip(b"=").decode()
        assert row == f"sha256={digest},{len(z.read(name))}", name
    assert set(rows) | {record} == set(z.namelist())  # every file listed, nothing listed that is gone
    return rows, z


def test_the_pruned_wheels_keep_the_variant_and_plugins_asked_for(wheels, tmp_path):
    out = tmp_path / "out"
    done = run(wheels, out, MI_VARIANTS="cuda_ad_rgb llvm_ad_rgb", MI_PLUGINS="ply merge aov")
    assert done.returncode == 0, done.stderr
    rows, z = listed(out / f"mitsuba-3.9.1-{TAG}.whl")
    assert set(rows) == {
        "mitsuba/__init__.py",
        "mitsuba/config.py",
        "mitsuba/libmitsuba.so",
        "mitsuba/libembree3.so",
        "mitsuba/mitsuba_ext.cpython-312-x86_64-linux-gnu.so",
        "mitsuba/python/util.py",
        "mitsuba/plugins/ply.so",
        "mitsuba/plugins/merge.so",
        "mitsuba/plugins/aov.so",
        "mitsuba/llvm_ad_rgb.cpython-312-x86_64-linux-gnu.so",
        "mitsuba/cuda_ad_rgb.cpython-312-x86_64-linux-gnu.so",
        "mitsuba-3.9.1.dist-info/METADATA",
        "mitsuba-3.9.1.dist-info/WHEEL",
    }
    assert z.read("mitsuba/libembree3.so") == b"mitsuba/libembree3.so"  # the bytes themselves
    assert (
        z.read("mitsuba/config.py").decode()
        == "PYTHON = 'x'\nMI_VARIANTS = ['cuda_ad_rgb', 'llvm_ad_rgb']\nOTHER = 1\n"
    )
    rows, _ = listed(out / f"drjit-1.5.0-{TAG}.whl")
    assert set(rows) == {"drjit/__init__.py", "drjit/libdrjit-core.so", "drjit-1.5.0.dist-info/METADATA"}
    assert (out / "trimesh-4.12.2-py3-none-any.whl").is_file()


def test_a_plugin_missing_from_the_wheel_or_no_wheel_is_refused(wheels, tmp_path):
    done = run(wheels, tmp_path / "out", MI_PLUGINS="ply nosuch")
    assert done.returncode != 0 and "has no mitsuba/plugins/nosuch.so" in done.stderr
    assert not list((tmp_path / "out").glob("mitsuba-*"))  # nothing half written
    (wheels / f"drjit-1.5.0-{TAG}.whl").unlink()
    done = run(wheels, tmp_path / "out")
    assert done.returncode == 2 and done.stderr.strip() == f"lease_wheels.sh mitsuba: {wheels}: needs one drjit-*.whl"


@pytest.mark.parametrize(
    "flags, line",
    [
        (["--size", "12"], "argument --size: WIDTHxHEIGHT, e.g. 1680x1050, got '12'"),
        (["--distance", "0.5"], "peers.py mitsuba: --distance: the eye must be outside the sphere, above 1, got 0.5"),
        ([], "peers.py mitsuba: Mitsuba 3 is not importable (no Mitsuba here)"),
    ],
)
def test_peers_mitsuba_refuses_in_one_line(tmp_path, flags, line):
    # a Mitsuba and a Dr.Jit that cannot be imported, whatever this machine has
    for name in ("drjit", "mitsuba"):
        (tmp_path / name).mkdir()
        (tmp_path / name / "__init__.py").write_text("raise ImportError('no Mitsuba here')\n")
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(tmp_path), str(ROOT / "src")])}
    done = subprocess.run([sys.executable, str(ROOT / "benchmarks" / "peers.py"), "mitsuba", *flags],
                          capture_output=True, text=True, env=env)  # fmt: skip
    assert done.returncode == 2
    lines = done.stderr.strip().splitlines()
    assert "Traceback" not in done.stderr and line in lines[-1]
    assert len(lines) == 1 or lines[0].startswith("usage:")  # argparse's usage above its line
