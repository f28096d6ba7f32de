"""The WGSL compute shader through wgpu: on lavapipe (Mesa's CPU Vulkan) in CI,
on whatever adapter is here otherwise. Same scenes, same float64 reference as
the CPU and CUDA tests, and the CPU's own pictures, through the BVH and by
brute force.

These tests skip where wgpu finds no adapter at all, except where
RAYBENCH_REQUIRE_WGPU=1 (CI sets it): there that is a failure.
"""

from __future__ import annotations

import ctypes.util
import json

import numpy as np
import pytest
from reference import check_frame, trace
from scenes import IN_VIEW, KINDS, SCENES, one_point

import raybench
from raybench import backends
from raybench.backends import options
from raybench.backends.options import checked
from raybench.backends.wgpu import adapters, compute
from raybench.cli import run
from raybench.render import Frame

pytestmark = pytest.mark.gpu


def same_as_cpu(gpu, cpu, ref, context):
    """Same hit indices wherever rounding cannot change the winner, colours
    within one step: lavapipe gives the CPU's bytes exactly (both round every
    operation to float32), but a GPU compiler may fuse multiply-adds."""
    same = (gpu.hits == cpu.hits) | ref.ambiguous
    assert same.all(), f"{context}: {np.count_nonzero(~same)} pixels hit another sphere than on the CPU"
    assert np.abs(gpu.image.astype(int) - cpu.image.astype(int)).max() <= 1, context


@pytest.mark.parametrize("accel", ["bvh", "none"])
@pytest.mark.parametrize("kind", sorted(KINDS))
@pytest.mark.parametrize("n", [1, 60])
def test_wgpu_matches_reference_and_cpu(adapter, rng, kind, n, accel):
    scene, camera = KINDS[kind](rng, n)
    for (width, height), workgroup in [((96, 64), (16, 16)), ((61, 37), (5, 3))]:
        context = f"{kind} n={n} {width}x{height} workgroup {workgroup} accel {accel}"
        gpu = raybench.render(
            scene, camera, width, height, device="wgpu", adapter=adapter, workgroup=workgroup, accel=accel
        )
        assert gpu.device == "wgpu"
        ref = trace(scene, camera, width, height)
        check_frame(gpu, ref, context=context)
        same_as_cpu(gpu, raybench.render(scene, camera, width, height, device="cpu"), ref, context)


def has_subgroups(adapter: str) -> bool:
    return compute.PACKET_FEATURE in adapters.choose(adapter).adapter.features


@pytest.mark.parametrize("walk", ["ray", "packet"])
@pytest.mark.parametrize("kind", sorted(SCENES))
def test_wgpu_bvh_gives_the_cpu_hits(adapter, rng, kind, walk):
    """The WGSL walks (a ray at a time, the default; packets of a subgroup's rays)
    against the CPU's brute force and the CPU's BVH, on fresh scenes and the
    degenerate ones (one point, a line, huge and tiny, one sphere, none,
    duplicates: ties everywhere). A CPU driver rounds every operation to
    float32 as the CPU does: the same hit in every pixel. A GPU compiler may
    fuse multiply-adds, which can tip a near-tie. The image's sides are no
    multiples of the workgroup's: the packets' invocations off the image
    vote too, and store nothing."""
    if walk == "packet" and not has_subgroups(adapter):
        pytest.skip("this adapter has no subgroups, which the packet walk needs")
    # from 100: fewer spheres around the camera of "inside" may all be out of view
    # (2% at 50), and the check below that something was hit would then fail
    n = int(rng.integers(100, 400))
    scene, camera = SCENES[kind](rng, n)
    width, height = 66, 47
    gpu = raybench.render(
        scene,
        camera,
        width,
        height,
        device="wgpu",
        adapter=adapter,  # the default: the BVH
        walk=walk,
    )
    assert gpu.build_s is not None
    brute = raybench.render(scene, camera, width, height, device="cpu", accel="none", kernel="simple")
    cpu_bvh = raybench.render(scene, camera, width, height, device="cpu", accel="bvh")
    differ = gpu.hits != brute.hits
    if adapters.choose(adapter).type == "CPU":
        assert not differ.any(), f"{kind}: {np.count_nonzero(differ)} pixels hit another sphere than on the CPU"
        assert np.array_equal(gpu.hits, cpu_bvh.hits)
    else:
        assert differ.mean() < 1e-3, (kind, np.count_nonzero(differ))
    assert np.abs(gpu.image.astype(int) - brute.image.astype(int))[~differ].max(initial=0) <= 1, kind
    if kind in IN_VIEW:  # not vacuous: something was hit
        assert (brute.hits >= 0).any()


def test_wgpu_bvh_ties_go_to_the_smaller_index(adapter, rng):
    """Identical spheres at one point: brute force shows the first in every
    pixel; the walk meets them in leaf order, and must show it too."""
    scene, camera = one_point(rng, 64)
    s = scene.spheres.copy()
    s[3] = 1.5
    same = raybench.Scene(s[0:3].T, s[3], s[4:7].T)
    frame = raybench.render(same, camera, 24, 16, device="wgpu", adapter=adapter, accel="bvh")
    assert set(np.unique(frame.hits)) <= {-1, 0} and (frame.hits == 0).any()


def test_every_pixel_is_written_whatever_the_workgroup(adapter, rng):
    """Workgroups that overhang the image must neither skip nor spill pixels;
    the thesis's 32x32 too, where the adapter allows 1024 invocations."""
    scene, camera = KINDS["generated"](rng, 10)
    width, height = 45, 23
    cpu = raybench.render(scene, camera, width, height, device="cpu")
    shapes = [(1, 1), (7, 5), (64, 1), (8, 32)]
    limits = adapters.choose(adapter).adapter.limits
    if limits["max-compute-invocations-per-workgroup"] >= 1024:
        shapes.append((32, 32))
    for workgroup in shapes:
        frame = raybench.render(scene, camera, width, height, device="wgpu", adapter=adapter, workgroup=workgroup)
        ref = trace(scene, camera, width, height)
        check_frame(frame, ref, context=f"workgroup {workgroup}")
        same_as_cpu(frame, cpu, ref, f"workgroup {workgroup}")
    one = raybench.render(scene, camera, 1, 1, device="wgpu", adapter=adapter)
    assert np.array_equal(one.hits, raybench.render(scene, camera, 1, 1, device="cpu").hits)


def test_the_packed_image_is_the_texture_read_back_as_it_is(adapter, rng):
    """trace() reads the RGB bytes packed on the GPU (pack.wgsl): they must be
    the texture's, read back the plain way (its RGBA rows copied out), at
    sizes whose pixel count is and is not a multiple of the four a word group packs."""
    import wgpu

    from raybench.backends.wgpu.tracer import Tracer

    scene, camera = KINDS["generated"](rng, int(rng.integers(1, 60)))
    for width, height in [(1, 1), (3, 1), (5, 3), (int(rng.integers(1, 90)), int(rng.integers(1, 40)))]:
        tracer = Tracer(scene.spheres, width, height, checked("wgpu", {"adapter": adapter}))
        image, _hits = tracer.trace(camera.basis(width, height))
        row_bytes = -(-width * 4 // 256) * 256
        plain = tracer.device.create_buffer(
            size=row_bytes * height, usage=wgpu.BufferUsage.COPY_DST | wgpu.BufferUsage.MAP_READ
        )
        encoder = tracer.device.create_command_encoder()
        encoder.copy_texture_to_buffer(
            {"texture": tracer.compute.texture, "mip_level": 0, "origin": (0, 0, 0)},
            {"buffer": plain, "offset": 0, "bytes_per_row": row_bytes, "rows_per_image": height},
            (width, height, 1),
        )
        tracer.device.queue.submit([encoder.finish()])
        plain.map_sync(wgpu.MapMode.READ)
        rgba = np.frombuffer(plain.read_mapped(), np.uint8).reshape(height, row_bytes // 4, 4)[:, :width]
        plain.unmap()
        assert np.array_equal(image, rgba[..., :3]), (width, height)
        tracer.close()


@pytest.mark.parametrize("accel", ["bvh", "none"])
def test_sphere_prefix_zero_spheres_and_reused_buffers(adapter, rng, accel):
    """What the benchmark and the viewer use: frames of the first k spheres
    (0 included) from one tracer, its buffers reused (the BVH rebuilt for
    each count), and a kernel time."""
    scene, camera = KINDS["cloud"](rng, 40)
    width, height = 50, 30
    basis = camera.basis(width, height)
    tracer = backends.tracer("wgpu", scene.spheres, width, height, adapter=adapter, accel=accel)
    try:
        assert tracer.compile() >= 0
        assert (tracer.build_s is not None) == (accel == "bvh")
        for k in [len(scene), 7, 0, len(scene) // 2]:
            image, hits = tracer.trace(basis, k)
            if accel == "bvh":
                assert tracer.compute.tree.count == k
            cpu = raybench.render(scene.head(k), camera, width, height, device="cpu")
            same_as_cpu(
                Frame(image, hits, "wgpu"), cpu, trace(scene.head(k), camera, width, height), f"first {k} spheres"
            )
        assert (hits >= -1).all() and (hits < len(scene) // 2).all()
        kernel_ms = tracer.timed_trace(basis, 3)
        assert kernel_ms > 0
        assert np.array_equal(tracer.hits, raybench.render(scene.head(3), camera, width, height, device="cpu").hits)
        with pytest.raises(raybench.RaybenchError, match="sphere count"):
            tracer.trace(basis, len(scene) + 1)
    finally:
        tracer.close()
    empty = raybench.render(
        raybench.Scene(np.zeros((0, 3)), [], np.zeros((0, 3))),
        width=33,
        height=17,
        device="wgpu",
        adapter=adapter,
        accel=accel,
    )
    assert (empty.hits == -1).all()
    assert np.array_equal(
        empty.image,
        raybench.render(
            raybench.Scene(np.zeros((0, 3)), [], np.zeros((0, 3))), width=33, height=17, device="cpu"
        ).image,
    )


@pytest.mark.parametrize(
    "options, match",
    [
        ({"workgroup": (0, 4)}, "workgroup"),
        ({"workgroup": (2048, 1)}, "workgroup"),
        ({"workgroup": (64, 64)}, "at most"),
        ({"workgroup": "ab"}, "workgroup: must be two integers"),
        ({"kernel": "fast"}, "simple kernel only"),
        ({"accel": "none", "kernel": "fast"}, "simple kernel only"),
        ({"accel": "bvh", "kernel": "simple"}, "kernel: applies to brute force only"),
        ({"accel": "kd-tree"}, "accel: must be one of bvh, none"),
        ({"threads": 2}, "does not apply to device wgpu"),
        ({"walk": "sideways"}, "walk: must be one of ray, packet, got 'sideways'"),
        ({"walk": "ray", "accel": "none"}, "walk: applies to the BVH walk only"),
    ],
)
def test_bad_options_are_refused(adapter, options, match):
    with pytest.raises(raybench.RaybenchError, match=match):
        raybench.render(raybench.random_spheres(3), width=8, height=8, device="wgpu", adapter=adapter, **options)


def test_wgpu_walks_a_ray_at_a_time_unless_asked_for_packets(adapter):
    """A ray at a time in 16x16 workgroups whatever the tree (the packets
    measured slower on the H200); packets, where asked for, in their own."""
    for n in (50, 30000):
        tracer = backends.tracer("wgpu", raybench.random_spheres(n).spheres, 16, 8, adapter=adapter)
        assert (tracer.walk, tracer.workgroup) == ("ray", options.DEFAULT_WORKGROUP["ray"])
    if has_subgroups(adapter):
        tracer = backends.tracer("wgpu", raybench.random_spheres(50).spheres, 16, 8, adapter=adapter, walk="packet")
        assert (tracer.walk, tracer.workgroup) == ("packet", options.DEFAULT_WORKGROUP["packet"])
    given = backends.tracer(
        "wgpu", raybench.random_spheres(50).spheres, 16, 8, adapter=adapter, walk="ray", workgroup=(4, 4)
    )
    assert (given.walk, given.workgroup) == ("ray", (4, 4))
    assert (
        backends.tracer("wgpu", raybench.random_spheres(5).spheres, 16, 8, adapter=adapter, accel="none").walk is None
    )


def test_packets_without_subgroups_are_refused_in_one_line(adapter):
    """A device without subgroups cannot run the packet walk: one line that
    says so, not a shader compiler's error (a device asked for without them)."""
    device = adapters.choose(adapter).adapter.request_device_sync(required_features=[])
    assert compute.PACKET_FEATURE not in device.features
    with pytest.raises(raybench.RaybenchError, match="walk: the packet walk votes with subgroup operations"):
        compute.Compute(device, raybench.random_spheres(3).spheres, 8, 8, checked("wgpu", {"walk": "packet"}))


def test_a_name_that_matches_no_adapter_lists_those_found(adapter):
    with pytest.raises(
        raybench.RaybenchError, match=r"adapter: none matches 'no-such-gpu' \(found: .*" + adapter.split(" ")[0]
    ):
        raybench.render(raybench.random_spheres(3), width=8, height=8, device="wgpu", adapter="no-such-gpu")


# --------------------------------------------------------------------------- adapter choice, on made-up adapters


def fake(name, backend, kind):
    return adapters.Adapter(name, backend, kind, object())


FAKES = (
    fake("llvmpipe (LLVM 15)", "Vulkan", "CPU"),
    fake("Intel(R) UHD 770", "Vulkan", "IntegratedGPU"),
    fake("NVIDIA RTX 4090", "OpenGL", "DiscreteGPU"),
    fake("NVIDIA RTX 4090", "Vulkan", "DiscreteGPU"),
    fake("SwiftShader Device", "Vulkan", "CPU"),
)


def found_these(monkeypatch, fakes):
    monkeypatch.setattr(adapters, "found", lambda: tuple(sorted(fakes, key=adapters.Adapter.rank)))


def test_unnamed_picks_a_discrete_gpu_then_an_integrated_one_never_a_cpu_driver(monkeypatch):
    found_these(monkeypatch, FAKES)
    assert (adapters.choose().name, adapters.choose().backend) == ("NVIDIA RTX 4090", "Vulkan")
    found_these(monkeypatch, [f for f in FAKES if f.type != "DiscreteGPU"])
    assert adapters.choose().name == "Intel(R) UHD 770"
    found_these(monkeypatch, [f for f in FAKES if f.type == "CPU"])
    with pytest.raises(raybench.RaybenchError) as err:
        adapters.choose()
    message = str(err.value)
    assert "no GPU adapter" in message and "llvmpipe (LLVM 15) (Vulkan, CPU)" in message
    assert "SwiftShader Device (Vulkan, CPU)" in message and "--adapter" in message
    assert "\n" not in message


def test_a_named_adapter_is_used_even_a_cpu_driver(monkeypatch):
    found_these(monkeypatch, FAKES)
    assert adapters.choose("LLVMPIPE").name == "llvmpipe (LLVM 15)"
    assert adapters.choose("swiftshader").name == "SwiftShader Device"
    assert adapters.choose("opengl").backend == "OpenGL"
    assert adapters.choose("4090").backend == "Vulkan"  # the native API before OpenGL
    with pytest.raises(raybench.RaybenchError, match="adapter: must be a non-empty name"):
        adapters.choose("  ")


def test_auto_takes_cuda_then_a_wgpu_gpu_then_the_cpu(monkeypatch):
    monkeypatch.setattr(backends, "cuda_available", lambda: False)
    found_these(monkeypatch, [f for f in FAKES if f.type == "CPU"])
    assert backends.resolve("auto") == "cpu" and backends.present() == ["cpu"]
    found_these(monkeypatch, FAKES)
    assert backends.resolve("auto") == "wgpu" and backends.present() == ["cpu", "wgpu"]
    monkeypatch.setattr(backends, "cuda_available", lambda: True)
    assert backends.resolve("auto") == "cuda"


def test_auto_asks_numba_cuda_only_where_nvidias_driver_loads(monkeypatch, tmp_path):
    """Importing numba-cuda to ask for a GPU costs seconds: "auto" first
    loads NVIDIA's driver library from where numba-cuda would, and asks
    numba-cuda only if that library loads."""
    asked = []

    class Found:
        available = staticmethod(lambda: True)
        simulated = staticmethod(lambda: False)

    monkeypatch.setattr(backends, "module", lambda name: asked.append(name) or Found)
    monkeypatch.setattr(backends, "_driver_candidates", lambda: [str(tmp_path / "libcuda.so.1")])
    assert not backends.cuda_available() and asked == []
    libc = ctypes.util.find_library("c")  # a library that loads, standing in for the driver
    monkeypatch.setattr(backends, "_driver_candidates", lambda: [str(tmp_path / "libcuda.so"), libc])
    assert backends.cuda_available() and asked == ["cuda"]


# --------------------------------------------------------------------------- the command line and the benchmark


def cli(capsys, *args):
    code = run([str(a) for a in args])
    captured = capsys.readouterr()
    return code, captured.out, captured.err


def one_error_line(code, out, err, *needles):
    assert code == 2 and "Traceback" not in out + err, (code, out, err)
    lines = err.splitlines()
    assert len(lines) == 1 and lines[0].startswith("raybench: error: "), err
    for needle in needles:
        assert needle in lines[0], (needle, lines[0])


def test_cli_render_on_wgpu_draws_the_cpu_picture(adapter, capsys, tmp_path):
    from PIL import Image

    args = ["render", "--spheres", 40, "--seed", 5, "--size", "70x50"]
    code, out, err = cli(
        capsys, *args, "--device", "wgpu", "--adapter", adapter, "--workgroup", "8x4", "-o", tmp_path / "wgpu.png"
    )
    assert code == 0, err
    assert "70x50, 40 spheres, wgpu" in out
    assert cli(capsys, *args, "--device", "cpu", "-o", tmp_path / "cpu.png")[0] == 0
    drawn, cpu = (np.asarray(Image.open(tmp_path / f"{d}.png")).astype(int) for d in ("wgpu", "cpu"))
    assert drawn.shape == (50, 70, 3) and np.abs(drawn - cpu).max() <= 1


def test_cli_render_on_wgpu_takes_accel(adapter, capsys, tmp_path):
    from PIL import Image

    args = ["render", "--spheres", 60, "--seed", 3, "--size", "48x32", "--device", "wgpu", "--adapter", adapter]
    pngs = {}
    for accel in ("bvh", "none"):
        code, out, err = cli(capsys, *args, "--accel", accel, "-o", tmp_path / f"{accel}.png")
        assert code == 0, err
        assert ("BVH built in" in out) == (accel == "bvh"), out
        pngs[accel] = np.asarray(Image.open(tmp_path / f"{accel}.png")).astype(int)
    assert np.abs(pngs["bvh"] - pngs["none"]).max() <= 1


@pytest.mark.parametrize(
    "extra, needles",
    [
        (["--workgroup", "0x4"], ["workgroup"]),
        (["--accel", "bvh", "--kernel", "simple"], ["kernel: applies to brute force only"]),
        (["--workgroup", "big"], ["--workgroup", "16x16"]),
        (["--adapter", "no-such-gpu"], ["adapter: none matches 'no-such-gpu'", "found:"]),
        (["--kernel", "fast"], ["simple kernel only"]),
        (["--block", "8x8"], ["'block' does not apply to device wgpu"]),
    ],
)
def test_cli_bad_wgpu_options_are_one_line(adapter, capsys, tmp_path, extra, needles):
    args = ["render", "--spheres", 3, "--size", "16x12", "--device", "wgpu", "-o", tmp_path / "x.png"]
    if "--adapter" not in extra:
        args += ["--adapter", adapter]
    one_error_line(*cli(capsys, *args, *extra), *needles)
    assert not (tmp_path / "x.png").exists()


def test_cli_wgpu_without_a_gpu_asks_for_the_adapter_by_name(adapter, capsys, tmp_path):
    if adapters.gpu_present():
        pytest.skip("this machine has a GPU adapter: device wgpu alone uses it")
    one_error_line(
        *cli(capsys, "render", "--spheres", 3, "--device", "wgpu", "-o", tmp_path / "x.png"),
        "no GPU adapter",
        "--adapter",
        adapter.split(" ")[0],
    )


def test_info_lists_the_adapters(adapter, capsys):
    code, out, err = cli(capsys, "info")
    assert code == 0, err
    # the wgpu section's first line names the best adapter (the GPU line above
    # it may name the same card, as on an NVIDIA machine)
    first = next((line for line in out.splitlines() if line.startswith("wgpu ")), "")
    best = adapters.found()[0]
    assert adapter in first and f"({best.backend}, {best.type})" in first, out
    code, out, err = cli(capsys, "info", "--json")
    assert {"name": best.name, "backend": best.backend, "type": best.type} in json.loads(out)["wgpu_adapters"]


def test_bench_points_for_wgpu():
    from raybench.bench import suites

    points = suites.points(
        ("thesis", "tuning", "constant-vs-runtime"),
        ("cpu", "wgpu"),
        quick=True,
        kernels=("fast", "simple"),
        wgpu={"adapter": "lavapipe"},
        max_invocations=256,
    )
    gpu = [p for p in points if p.device == "wgpu"]
    assert gpu and all(p.options["kernel"] == "simple" and p.options["adapter"] == "lavapipe" for p in gpu)
    assert {p.test for p in gpu if p.suite == "thesis"} == {1}  # a GPU's tests: 1-3
    assert not [p for p in gpu if p.suite == "constant-vs-runtime"]  # no compile-time count on wgpu
    shapes = [tuple(p.options["workgroup"]) for p in gpu if p.suite == "tuning"]
    assert shapes and all(x * y <= 256 for x, y in shapes) and (16, 16) in shapes and (32, 32) not in shapes
    # once per kernel for the cpu, once for wgpu (its one kernel)
    assert len([p for p in gpu if p.suite == "test7"]) == 1
    assert len([p for p in points if p.device == "cpu" and p.suite == "test7"]) == 2


def test_bench_points_for_wgpu_bvh():
    """wgpu takes accel bvh like the other devices: the BVH's points beside
    brute force's (simple, once, whatever the kernels), or alone."""
    from raybench.bench import suites

    both = suites.points(
        ("thesis", "tuning", "scaling"),
        ("cpu", "wgpu"),
        quick=True,
        kernels=("fast", "simple"),
        accels=("bvh", "none"),
        wgpu={"adapter": "lavapipe"},
        max_invocations=1024,
    )
    gpu = [p for p in both if p.device == "wgpu"]
    ways = {(p.suite, p.options["accel"], p.options.get("kernel")) for p in gpu}
    assert ways == {
        (suite, accel, kernel)
        for suite in ("thesis", "tuning", "scaling")
        for accel, kernel in (("bvh", None), ("none", "simple"))
    } | {("test7", "none", "simple")}
    scaling = [p for p in gpu if p.suite == "scaling" and p.options["accel"] == "bvh"]
    even = [p.spheres for p in scaling if "layout" not in p.options]
    assert even == list(suites.QUICK_SCALING_COUNTS)
    # the denser layouts' points beside them, BVH only, as on every device
    denser = sorted((p.options["layout"], p.spheres) for p in scaling if "layout" in p.options)
    assert denser == sorted((lay, n) for lay in suites.SCALING_LAYOUTS for n in suites.QUICK_SCALING_LAYOUT_COUNTS)
    assert all("cap_s" not in p.options for p in scaling)  # only brute force is capped
    shapes = {tuple(p.options["workgroup"]) for p in gpu if p.suite == "tuning" and p.options["accel"] == "bvh"}
    assert (32, 32) in shapes  # the adapter's limit, not the CUDA walk's register bound
    bvh_only = suites.points(("thesis", "scaling"), ("wgpu",), quick=True, accels=("bvh",))
    assert bvh_only and all(p.options == {"accel": "bvh"} for p in bvh_only if "layout" not in p.options)


@pytest.mark.parametrize("way", [{"accel": "none", "kernel": "simple"}, {"accel": "bvh"}])
def test_a_benchmark_record_names_the_adapter(adapter, way):
    from raybench.bench import runner, suites

    point = suites.Point("thesis", "wgpu", 32, 24, 20, {**way, "adapter": adapter}, test=1)
    record = runner.measure(point, runner.Scenes(0), 0.05)
    assert (record["build_s"] is not None) == (way["accel"] == "bvh")
    assert record["adapter"]["name"] == adapters.choose(adapter).name
    assert record["adapter"]["type"] == adapters.choose(adapter).type and record["adapter"]["workgroup"] == [16, 16]
    assert record["kernel_ms"]["median"] > 0 and record["frames"] >= runner.MIN_FRAMES


@pytest.mark.slow
def test_cpu_use_never_imports_wgpu(tmp_path):
    """wgpu (and its driver probing) loads only when wgpu or auto is asked for."""
    import subprocess
    import sys

    code = (
        "import sys, raybench\n"
        "from raybench.cli import run\n"
        "raybench.render(raybench.random_spheres(3), width=8, height=8, device='cpu')\n"
        f"out = {str(tmp_path / 'x.png')!r}\n"
        "assert run(['render', '--spheres', '3', '--size', '8x8', '--device', 'cpu', '-o', out]) == 0\n"
        "import raybench.backends.wgpu\n"
        "assert 'wgpu' not in sys.modules, 'wgpu was imported'\n"
    )
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=600)
    assert proc.returncode == 0, proc.stderr


def test_kernel_time_without_timestamps_is_the_wall_time_of_the_pass(adapter, rng):
    """Where an adapter has no timestamp queries (or their period cannot be
    read) the pass is timed by the wall clock around its completed submission."""
    scene, camera = KINDS["generated"](rng, 30)
    width, height = 40, 24
    tracer = backends.tracer("wgpu", scene.spheres, width, height, adapter=adapter)
    try:
        tracer.period_ns = None
        assert tracer.describe()["timing"] == "wall clock"
        assert tracer.timed_trace(camera.basis(width, height)) > 0
        assert np.array_equal(tracer.hits, raybench.render(scene, camera, width, height, device="cpu").hits)
    finally:
        tracer.close()
