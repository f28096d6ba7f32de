"""The command line: every user mistake is one line on stderr, exit code 2, and no file written."""

from __future__ import annotations

import json
import os
import subprocess
import sys

import numpy as np
import pytest
from PIL import Image

import raybench
from raybench import Camera, Scene, backends, random_spheres
from raybench.backends import cuda_available
from raybench.cli import run

ERROR_PREFIX = "raybench: error:"
TINY = ["--size", "16x12", "--device", "cpu"]


@pytest.fixture(autouse=True)
def in_tmp(tmp_path, monkeypatch):
    """Run every test from its own empty folder, so that a default -o render.png
    could only land there (and would then be caught by the file checks)."""
    monkeypatch.chdir(tmp_path)
    return tmp_path


def tree(folder) -> set[str]:
    """Every file and folder under folder, hidden ones included."""
    return {str(p.relative_to(folder)) for p in folder.rglob("*")}


def cli(capsys, *args):
    code = run([str(a) for a in args])
    captured = capsys.readouterr()
    return code, captured.out, captured.err


def assert_user_error(code, out, err, *needles):
    """Exit code 2, one non-empty line on stderr starting with the prefix and
    naming every needle, no traceback anywhere; returns the line."""
    assert "Traceback" not in out + err, out + err
    assert code == 2, f"exit code {code}; stdout {out!r}; stderr {err!r}"
    lines = err.splitlines()
    assert len(lines) == 1 and lines[0].strip(), f"want exactly one stderr line, got {err!r}"
    line = lines[0]
    assert line.startswith(ERROR_PREFIX + " "), line
    assert len(line) > len(ERROR_PREFIX) + 5, line
    for needle in needles:
        assert str(needle) in line, f"{needle!r} not in {line!r}"
    return line


def expect_error(capsys, tmp_path, args, *needles):
    """Run args in-process; check the error and that tmp_path did not change."""
    before = tree(tmp_path)
    code, out, err = cli(capsys, *args)
    line = assert_user_error(code, out, err, *needles)
    after = tree(tmp_path)
    assert after == before, f"files appeared or vanished: {sorted(after ^ before)}"
    return line


def run_subprocess(tmp_path, *args, env=None):
    before = tree(tmp_path)
    proc = subprocess.run(
        [sys.executable, "-m", "raybench", *map(str, args)],
        cwd=tmp_path,
        env=env,
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert tree(tmp_path) == before, sorted(tree(tmp_path) ^ before)
    return proc.returncode, proc.stdout, proc.stderr


def write_doc(path, **changes):
    doc = {
        "format": "raybench-scene",
        "version": 1,
        "spheres": [
            {"center": [0, 0, 5], "radius": 1, "color": [1, 0.5, 0.25]},
            {"center": [1, 0, 7], "radius": 0.5, "color": [0.2, 0.4, 0.6]},
        ],
    }
    for index, sphere_changes in changes.get("spheres", {}).items():
        doc["spheres"][index].update(sphere_changes)
    path.write_text(json.dumps(doc))
    return path


@pytest.fixture
def scene_file(tmp_path):
    path = tmp_path / "scene.json"
    spheres = random_spheres(12, 4)
    Scene(
        spheres.centers, spheres.radii, spheres.colors, Camera(position=(0, 0, -1), look_at=(0, 0, 10), fov_deg=55)
    ).save(path)
    return path


@pytest.fixture
def out_dir(tmp_path):
    folder = tmp_path / "out"
    folder.mkdir()
    return folder


# --------------------------------------------------------------------------- bad scene files


def test_malformed_json_scene(capsys, tmp_path, out_dir):
    bad = tmp_path / "broken.json"
    bad.write_text('{"format": "raybench-scene", "version": 1, "spheres": [')
    expect_error(
        capsys, tmp_path, ["render", "--scene", bad, *TINY, "-o", out_dir / "x.png"], "broken.json", "not valid JSON"
    )


def test_scene_with_unknown_field(capsys, tmp_path, out_dir):
    bad = write_doc(tmp_path / "unknown.json", spheres={1: {"shininess": 3}})
    expect_error(
        capsys,
        tmp_path,
        ["render", "--scene", bad, *TINY, "-o", out_dir / "x.png"],
        "unknown.json",
        "spheres[1].shininess",
        "unknown field",
    )


def test_scene_with_negative_radius(capsys, tmp_path, out_dir):
    bad = write_doc(tmp_path / "negative.json", spheres={0: {"radius": -2}})
    expect_error(
        capsys,
        tmp_path,
        ["render", "--scene", bad, *TINY, "-o", out_dir / "x.png"],
        "negative.json",
        "spheres[0].radius",
        "> 0",
    )


@pytest.mark.parametrize("color", [[0.5, 1.5, 0.5], [-0.1, 0.5, 0.5]])
def test_scene_with_color_out_of_range(capsys, tmp_path, out_dir, color):
    bad = write_doc(tmp_path / "color.json", spheres={1: {"color": color}})
    expect_error(
        capsys,
        tmp_path,
        ["render", "--scene", bad, *TINY, "-o", out_dir / "x.png"],
        "color.json",
        "spheres[1].color",
        "[0, 1]",
    )


def test_scene_file_that_does_not_exist(capsys, tmp_path, out_dir):
    expect_error(
        capsys, tmp_path, ["render", "--scene", tmp_path / "nope.json", *TINY, "-o", out_dir / "x.png"], "nope.json"
    )


# --------------------------------------------------------------------------- --size


@pytest.mark.parametrize(
    "size,needles",
    [
        ("0x600", ["width", "got 0"]),
        ("600x0", ["height", "got 0"]),
        ("800", ["--size", "'800'"]),
        ("abcxdef", ["--size", "abcxdef"]),
        ("-8x6", ["--size", "-8x6"]),
        ("8x6x4", ["--size", "8x6x4"]),
        ("100000x100", ["width", "65536", "100000"]),
        ("100x100000", ["height", "65536", "100000"]),
    ],
)
def test_bad_size(capsys, tmp_path, out_dir, size, needles):
    expect_error(
        capsys,
        tmp_path,
        ["render", "--spheres", 3, "--size", size, "--device", "cpu", "-o", out_dir / "x.png"],
        *needles,
    )


def test_size_beyond_memory(capsys, tmp_path, out_dir):
    import psutil

    need = 65536 * 65536 * 14  # colour and hit buffers, held twice on the host
    if psutil.virtual_memory().available > need:
        pytest.skip(f"this machine has more than {need / 2**30:.0f} GiB available; the frame would fit")
    line = expect_error(
        capsys,
        tmp_path,
        ["render", "--spheres", 3, "--size", "65536x65536", "--device", "cpu", "-o", out_dir / "x.png"],
        "65536x65536",
        "GiB",
        "cpu",
    )
    assert "56.00 GiB" in line, line  # 65536 * 65536 * 14 bytes + 3 spheres


# --------------------------------------------------------------------------- --device


def test_unknown_device(capsys, tmp_path, out_dir):
    expect_error(
        capsys,
        tmp_path,
        ["render", "--spheres", 3, "--size", "16x12", "--device", "tpu", "-o", out_dir / "x.png"],
        "--device",
        "tpu",
    )


def test_cuda_without_gpu(tmp_path, out_dir):
    """The real check, in a process with numba's simulator off (tests/conftest.py
    turns it on where there is no GPU, and under it --device cuda runs the simulator)."""
    if cuda_available():
        pytest.skip("a usable CUDA GPU is present; the no-GPU error cannot happen here")
    env = dict(os.environ, NUMBA_ENABLE_CUDASIM="0")
    code, out, err = run_subprocess(
        tmp_path, "render", "--spheres", 3, "--size", "16x12", "--device", "cuda", "-o", out_dir / "x.png", env=env
    )
    line = assert_user_error(code, out, err, "cuda")
    assert "--device cpu" in line, line


def test_cuda_unavailable_in_process(capsys, tmp_path, out_dir, monkeypatch):
    """The same error through run(), with the backend told there is no device
    (in this process the simulator may be on, which would otherwise render)."""
    try:
        cuda_backend = backends.module("cuda")
    except ImportError:
        pass  # numba-cuda missing: run() meets the real ImportError path below
    else:
        monkeypatch.setattr(cuda_backend.device, "available", lambda: False)
    line = expect_error(
        capsys,
        tmp_path,
        ["render", "--spheres", 3, "--size", "16x12", "--device", "cuda", "-o", out_dir / "x.png"],
        "device cuda",
    )
    assert "--device cpu" in line, line


# --------------------------------------------------------------------------- -o


def test_output_in_missing_folder(capsys, tmp_path):
    target = tmp_path / "missing" / "x.png"
    expect_error(capsys, tmp_path, ["render", "--spheres", 3, *TINY, "-o", target], str(target), "does not exist")
    assert not (tmp_path / "missing").exists()


def test_output_is_a_folder(capsys, tmp_path):
    folder = tmp_path / "picture.png"
    folder.mkdir()
    expect_error(capsys, tmp_path, ["render", "--spheres", 3, *TINY, "-o", folder], "picture.png", "folder")
    assert folder.is_dir() and not any(folder.iterdir())


def test_output_is_a_plain_folder(capsys, tmp_path, out_dir):
    expect_error(capsys, tmp_path, ["render", "--spheres", 3, *TINY, "-o", out_dir], str(out_dir))


def test_output_jpg(capsys, tmp_path, out_dir):
    expect_error(capsys, tmp_path, ["render", "--spheres", 3, *TINY, "-o", out_dir / "x.jpg"], "x.jpg", ".png")


@pytest.mark.skipif(
    hasattr(os, "geteuid") and os.geteuid() == 0,
    reason="running as root: os.access() reports every folder writable, so a read-only "
    "folder cannot be simulated with chmod",
)
def test_output_in_read_only_folder(capsys, tmp_path):
    folder = tmp_path / "locked"
    folder.mkdir()
    folder.chmod(0o500)
    try:
        expect_error(
            capsys, tmp_path, ["render", "--spheres", 3, *TINY, "-o", folder / "x.png"], "x.png", "not writable"
        )
        assert list(folder.iterdir()) == []
    finally:
        folder.chmod(0o700)


def test_output_in_unwritable_folder_as_seen_by_os_access(capsys, tmp_path, monkeypatch):
    """The read-only case where chmod cannot show it (root): os.access says no."""
    folder = tmp_path / "locked"
    folder.mkdir()
    real_access = os.access

    def access(path, mode, *args, **kwargs):
        if mode & os.W_OK and os.path.abspath(path) in (str(folder), str(folder / "x.png")):
            return False
        return real_access(path, mode, *args, **kwargs)

    monkeypatch.setattr(os, "access", access)
    expect_error(capsys, tmp_path, ["render", "--spheres", 3, *TINY, "-o", folder / "x.png"], "x.png", "not writable")
    assert list(folder.iterdir()) == []


# --------------------------------------------------------------------------- --scene / --spheres / --seed


def test_scene_and_spheres(capsys, tmp_path, scene_file, out_dir):
    expect_error(
        capsys,
        tmp_path,
        ["render", "--scene", scene_file, "--spheres", 3, *TINY, "-o", out_dir / "x.png"],
        "--scene",
        "--spheres",
    )


def test_neither_scene_nor_spheres(capsys, tmp_path, out_dir):
    expect_error(capsys, tmp_path, ["render", *TINY, "-o", out_dir / "x.png"], "--scene", "--spheres")


def test_neither_scene_nor_spheres_default_output(capsys, tmp_path):
    # Without -o the default render.png would land in the current folder (tmp_path).
    expect_error(capsys, tmp_path, ["render", *TINY], "--scene", "--spheres")


def test_seed_with_scene(capsys, tmp_path, scene_file, out_dir):
    expect_error(
        capsys, tmp_path, ["render", "--scene", scene_file, "--seed", 3, *TINY, "-o", out_dir / "x.png"], "--seed"
    )


def test_layout_with_scene(capsys, tmp_path, scene_file, out_dir):
    expect_error(
        capsys, tmp_path, ["render", "--scene", scene_file, "--layout", "dense", *TINY, "-o", out_dir / "x.png"],
        "--layout",
    )  # fmt: skip


def test_render_layout_is_random_spheres_layout(capsys, tmp_path, out_dir):
    """--layout: the picture of random_spheres(n, seed, layout=...), not the even spread's."""
    from raybench import random_spheres, render

    got = {}
    for layout in ("clusters", None):
        extra = ["--layout", layout] if layout else []
        target = out_dir / f"{layout}.png"
        code, out, err = cli(capsys, "render", "--spheres", 300, "--seed", 4, *extra, *TINY, "-o", target)
        assert code == 0, err
        got[layout] = read_png(target)[2]
    want = render(random_spheres(300, 4, layout="clusters"), None, 16, 12, device="cpu").image
    assert np.array_equal(got["clusters"], want) and not np.array_equal(got["clusters"], got[None])


@pytest.mark.parametrize("count", [-1, 100_000_001])
def test_bad_sphere_count(capsys, tmp_path, out_dir, count):
    expect_error(
        capsys, tmp_path, ["render", "--spheres", count, *TINY, "-o", out_dir / "x.png"], "sphere count", str(count)
    )


def test_spheres_not_a_number(capsys, tmp_path, out_dir):
    expect_error(capsys, tmp_path, ["render", "--spheres", "many", *TINY, "-o", out_dir / "x.png"], "--spheres", "many")


# --------------------------------------------------------------------------- --threads / --block


@pytest.mark.parametrize("threads", [0, 10000, -1])
def test_bad_threads(capsys, tmp_path, out_dir, threads):
    expect_error(
        capsys,
        tmp_path,
        ["render", "--spheres", 3, *TINY, "--threads", threads, "-o", out_dir / "x.png"],
        "threads",
        f"got {threads}",
    )


def test_block_on_cpu(capsys, tmp_path, out_dir):
    expect_error(
        capsys, tmp_path, ["render", "--spheres", 3, *TINY, "--block", "8x8", "-o", out_dir / "x.png"], "block", "cpu"
    )


def test_unknown_option(capsys, tmp_path, out_dir):
    expect_error(
        capsys, tmp_path, ["render", "--spheres", 3, *TINY, "--colour", "red", "-o", out_dir / "x.png"], "--colour"
    )


# --------------------------------------------------------------------------- subprocess: no traceback


@pytest.mark.parametrize(
    "args,needles",
    [
        (["--size", "abcxdef", "--device", "cpu"], ["--size", "abcxdef"]),
        (["--size", "16x12", "--device", "tpu"], ["--device", "tpu"]),
        (["--size", "16x12", "--device", "cpu", "--threads", "0"], ["threads"]),
    ],
    ids=["bad-size", "unknown-device", "threads-0"],
)
def test_subprocess_error_is_one_line(tmp_path, out_dir, args, needles):
    code, out, err = run_subprocess(tmp_path, "render", "--spheres", 3, *args, "-o", out_dir / "x.png")
    assert_user_error(code, out, err, *needles)
    assert out == ""


def test_subprocess_malformed_scene(tmp_path, out_dir):
    bad = tmp_path / "broken.json"
    bad.write_text("{ nope")
    code, out, err = run_subprocess(tmp_path, "render", "--scene", bad, *TINY, "-o", out_dir / "x.png")
    assert_user_error(code, out, err, "broken.json", "not valid JSON")
    assert out == ""


# --------------------------------------------------------------------------- things that work


def read_png(path):
    with Image.open(path) as img:
        assert img.format == "PNG"
        img.load()
        return img.size, img.mode, np.asarray(img)


def test_render_random_spheres(capsys, tmp_path, out_dir):
    code, out, err = cli(
        capsys, "render", "--spheres", 20, "--size", "64x48", "--device", "cpu", "-o", out_dir / "out.png"
    )
    assert code == 0, err
    assert err == "" and "Traceback" not in out
    assert "64x48" in out and "20 spheres" in out and "cpu" in out
    assert sorted(p.name for p in out_dir.iterdir()) == ["out.png"]
    size, mode, pixels = read_png(out_dir / "out.png")
    assert size == (64, 48) and mode == "RGB"
    expected = raybench.render(random_spheres(20, 0), width=64, height=48, device="cpu").image
    assert np.array_equal(pixels, expected)
    # Some spheres and some background are visible: a real picture.
    assert len(np.unique(pixels.reshape(-1, 3), axis=0)) > 10


def test_render_overwrites_existing_output(capsys, tmp_path, out_dir):
    target = out_dir / "out.png"
    target.write_bytes(b"old")
    code, out, err = cli(capsys, "render", "--spheres", 5, "--seed", 9, *TINY, "--threads", 1, "-o", target)
    assert code == 0, err
    assert sorted(p.name for p in out_dir.iterdir()) == ["out.png"]
    assert read_png(target)[0] == (16, 12)


def test_render_scene_file(capsys, tmp_path, scene_file, out_dir):
    code, out, err = cli(
        capsys, "render", "--scene", scene_file, "--size", "40x30", "--device", "cpu", "-o", out_dir / "scene.png"
    )
    assert code == 0, err
    assert err == ""
    assert sorted(p.name for p in out_dir.iterdir()) == ["scene.png"]
    size, mode, pixels = read_png(out_dir / "scene.png")
    assert size == (40, 30) and mode == "RGB"
    scene = Scene.load(scene_file)
    # The scene's own camera is used.
    assert np.array_equal(pixels, raybench.render(scene, width=40, height=30, device="cpu").image)


def test_render_default_output_name(capsys, tmp_path):
    code, out, err = cli(capsys, "render", "--spheres", 4, *TINY)
    assert code == 0, err
    assert tree(tmp_path) == {"render.png"}
    assert read_png(tmp_path / "render.png")[0] == (16, 12)


def test_info(capsys):
    code, out, err = cli(capsys, "info")
    assert code == 0, err
    assert "Traceback" not in out + err
    lines = out.splitlines()
    assert any(line.startswith("CPU") for line in lines), out
    assert any(line.startswith("Versions") for line in lines), out
    assert any(line.startswith("GPU") for line in lines), out
    assert f"raybench {raybench.__version__}" in out


def test_info_json(capsys):
    code, out, err = cli(capsys, "info", "--json")
    assert code == 0, err
    desc = json.loads(out)
    assert {"cpu", "gpus", "versions"} <= set(desc)
    assert isinstance(desc["gpus"], list)
    assert desc["cpu"]["logical_cpus"] >= 1
    assert desc["versions"]["raybench"] == raybench.__version__


@pytest.mark.parametrize(
    "args,needle",
    [
        (["--help"], "render"),
        (["-h"], "info"),
        (["render", "--help"], "--size"),
        (["info", "--help"], "--json"),
    ],
)
def test_help(capsys, args, needle):
    code, out, err = cli(capsys, *args)
    assert code == 0, err
    assert needle in out and "Usage:" in out
    assert err == ""


def test_version(capsys):
    code, out, err = cli(capsys, "--version")
    assert code == 0, err
    assert raybench.__version__ in out


# --------------------------------------------------------------------------- found bugs, fixed


def test_size_with_superscript_digit(capsys, tmp_path, out_dir):
    expect_error(
        capsys,
        tmp_path,
        ["render", "--spheres", 3, "--size", "²x3", "--device", "cpu", "-o", out_dir / "x.png"],
        "--size",
    )


def test_scene_with_huge_integer(capsys, tmp_path, out_dir):
    bad = tmp_path / "huge.json"
    bad.write_text(
        '{"format": "raybench-scene", "version": 1, "spheres": '
        '[{"center": [0, 0, 5], "radius": 1' + "0" * 400 + ', "color": [1, 1, 1]}]}'
    )
    expect_error(capsys, tmp_path, ["render", "--scene", bad, *TINY, "-o", out_dir / "x.png"], "spheres[0].radius")


def test_render_kernels_draw_the_same_png(capsys, tmp_path):
    pngs = {}
    for kernel in ("simple", "fast"):
        code, out, err = cli(
            capsys,
            "render",
            "--spheres",
            60,
            "--seed",
            4,
            "--size",
            "67x45",
            "--device",
            "cpu",
            "--kernel",
            kernel,
            "-o",
            tmp_path / f"{kernel}.png",
        )
        assert code == 0, err
        pngs[kernel] = np.asarray(Image.open(tmp_path / f"{kernel}.png"))
    assert np.array_equal(pngs["simple"], pngs["fast"])
    code, out, err = cli(capsys, "render", "--spheres", 3, "--kernel", "quick", "-o", tmp_path / "x.png")
    assert_user_error(code, out, err, "--kernel", "quick")
    assert not (tmp_path / "x.png").exists()


def test_render_accel_bvh_and_none_same_png(tmp_path, capsys):
    pngs = {}
    for accel in ("bvh", "none"):
        code, out, err = cli(
            capsys,
            "render",
            "--spheres",
            200,
            "--size",
            "48x30",
            "--device",
            "cpu",
            "--accel",
            accel,
            "-o",
            tmp_path / f"{accel}.png",
        )
        assert code == 0, err
        assert ("BVH built in" in out) == (accel == "bvh")
        pngs[accel] = np.asarray(Image.open(tmp_path / f"{accel}.png"))
    assert np.array_equal(pngs["bvh"], pngs["none"])
    code, out, err = cli(
        capsys, "render", "--spheres", 3, "--accel", "bvh", "--kernel", "simple", "-o", tmp_path / "x.png"
    )
    assert_user_error(code, out, err, "kernel", "brute force only")
    assert not (tmp_path / "x.png").exists()


def test_warmup_refuses_an_unknown_device(capsys):
    code, out, err = cli(capsys, "warmup", "--device", "tpu")
    assert code == 2 and err.strip() == "raybench: error: --device: unknown device 'tpu'; choose from cpu, cuda, wgpu"


def test_build_option_on_a_device_without_it_is_one_line(capsys, tmp_path):
    """--build is cuda's and wgpu's (where the BVH is built); cpu refuses it,
    and bench without cuda or wgpu among its devices too; a bad value is
    click's one line."""
    out = tmp_path / "x.png"
    expect_error(
        capsys, tmp_path, ["render", "--spheres", 3, *TINY, "--build", "gpu", "-o", out], "'build'", "device cpu"
    )
    expect_error(capsys, tmp_path, ["render", "--spheres", 3, *TINY, "--build", "sideways", "-o", out], "--build")
    expect_error(
        capsys, tmp_path, ["bench", "--device", "cpu", "--build", "gpu", "--out", tmp_path / "r"], "--build", "cuda"
    )


def test_render_png_level(capsys, tmp_path, out_dir):
    """--png-level 0 stores the pixels uncompressed, the default (1) deflates them; the pixels are the same."""
    files = {}
    for name, level in (("stored", ["--png-level", 0]), ("default", [])):
        files[name] = out_dir / f"{name}.png"
        code, out, err = cli(capsys, "render", "--spheres", 20, "--size", "64x48", "--device", "cpu", *level,
                             "-o", files[name])  # fmt: skip
        assert code == 0, err
    assert np.array_equal(read_png(files["stored"])[2], read_png(files["default"])[2])
    raw = 64 * 48 * 3 + 48  # the pixels and a filter byte a row
    assert files["stored"].stat().st_size > raw > files["default"].stat().st_size


@pytest.mark.parametrize("level", ["10", "-1"])
def test_render_png_level_out_of_range(capsys, tmp_path, out_dir, level):
    expect_error(capsys, tmp_path, ["render", "--spheres", 3, *TINY, "--png-level", level, "-o", out_dir / "x.png"],
                 "PNG level", "0", "9", level)  # fmt: skip


@pytest.mark.parametrize(
    "extra, needles",
    [([], ["--gif applies to --path only"]), (["--path", "orbit"], ["--gif", "out.png", "must be a .gif file"])],
)
def test_render_gif_refused_before_work(capsys, tmp_path, out_dir, extra, needles):
    gif = "out.gif" if not extra else "out.png"
    expect_error(capsys, tmp_path, ["render", "--spheres", 3, *TINY, *extra, "--gif", out_dir / gif,
                                    "-o", out_dir / ("frames" if extra else "x.png")], *needles)  # fmt: skip
