"""Triangle meshes' trees built on the GPU, and the memory a large mesh's frame takes, as records
of the results schema's "parts" suite (options primitive "triangle", triangles, mesh):

- the GPU build over a mesh's triangles, on cuda (gpu_build.py's gpu_build: CUDA events around
  its kernels, --repeats builds, and the wall time to the tree ready) and through wgpu
  (wgpu_build.py's gpu_build_times: GPU timestamps), each quality in --quality, beside the host's
  binned SAH build of the same triangles (quantity "bvh-build");
- with --memory N, a frame of N random triangles (or, with --memory-mesh icosphere, an icosphere
  of N triangles, whose triangles share their vertices; 1680x1050, primary rays, the BVH) on each
  --memory-device: the memory it takes beyond what the process held with the mesh already made
  and the kernels compiled (a first frame of a small mesh, the builder's ways compiled too), its
  peak polled every millisecond through the tracer's making, its tree's build and a frame: on
  cuda the GPU's used memory (NVML), on the cpu the process's resident set. Quantity
  "mesh-memory": the times are the frames'; values give the peak in bytes, the mesh's own bytes
  (its float32 vertices and int32 faces) and their ratio.

The meshes: trimesh.creation.icosphere(subdivisions, radius 1) at each --subdivisions
(20 * 4^k triangles: 8 gives 1,310,720), and --random N triangles (random_triangles below).

    PYTHONPATH=src python benchmarks/mesh_build.py --device cuda --device wgpu \\
        --subdivisions 8 --random 1000000 --memory 10000000 --memory-device cuda --memory-device cpu --out b.jsonl
"""

from __future__ import annotations

import argparse
import ctypes
import gc
import math
import sys
import threading
import time

import _harness
import numpy as np
from _embreex import icosphere

from raybench import backends, bvh
from raybench.bvh.sah_steps import WIDE
from raybench.camera import Camera
from raybench.kernels.primitives import triangle_mesh
from raybench.meshes import MESH_COLOUR, Mesh, Painted, mesh_leaves

SIZE = (1680, 1050)


def random_triangles(n: int, seed: int = 0) -> Mesh:
    """n triangles, each of its own three vertices: centres uniform in the cube [-1, 1]^3, each
    corner within half an edge s of its centre on every axis, s = 2 / n^(1/3) (the cube's side
    over the triangles a side), so that the triangles fill the cube about once whatever n."""
    rng = np.random.default_rng(seed)
    s = 2.0 / n ** (1.0 / 3.0)
    centres = rng.uniform(-1.0, 1.0, (n, 1, 3)).astype(np.float32)
    vertices = (centres + rng.uniform(-0.5 * s, 0.5 * s, (n, 3, 3)).astype(np.float32)).reshape(-1, 3)
    return Mesh(vertices, np.arange(3 * n, dtype=np.int32).reshape(n, 3), None)


def meshes(args):
    for k in args.subdivisions or []:
        yield f"icosphere {k}", icosphere(k)
    for n in args.random or []:
        yield f"random {n}", random_triangles(n)


def options(name: str, n: int, **more) -> dict:
    return {"primitive": "triangle", "triangles": n, "mesh": name.split()[0], **more}


def builds(name: str, mesh: Mesh, args) -> list[dict]:
    leaves = mesh_leaves(mesh, MESH_COLOUR)
    n = leaves.shape[1]
    bvh.compile_builder()
    times = [
        bvh.build(leaves, device="cuda", primitive=_kind()).build_s * 1e3 for _ in range(max(3, args.repeats // 5))
    ]
    out = [_harness.part("bvh-build", "cpu", times, options=options(name, n))]
    for device in args.device or ["cuda"]:
        for quality in args.quality or ["sah"]:
            try:
                timings, figures = _gpu_build(device, leaves, args.repeats, quality)
            except Exception as exc:  # noqa: BLE001 (a quality or device that fails is said, the others still measured)
                print(f"{name}: {device} {quality}: {type(exc).__name__}: {exc}", file=sys.stderr)
                continue
            for quantity, ms in timings.items():
                out.append(_harness.part(quantity, device, ms, options=options(name, n, quality=quality),
                                         values=figures))  # fmt: skip
    return out


def _kind():
    from raybench.kernels.primitives import triangle

    return triangle


def _gpu_build(device: str, leaves: np.ndarray, repeats: int, quality: str):
    if device == "cuda":
        import gpu_build

        return gpu_build.gpu_build(leaves, repeats, quality, gpu_build.lbvh.TREELET_PASSES, primitive="triangle")
    import wgpu_build

    from raybench.backends.wgpu import adapters

    device = adapters.request_device(adapters.choose(None))
    return wgpu_build.gpu_build_times(device, leaves, repeats, quality, primitive="triangle")


class _Nvml:
    """The GPU's used memory in bytes, through NVML (the driver's library; no package needed)."""

    class _Info(ctypes.Structure):
        _fields_ = [("total", ctypes.c_ulonglong), ("free", ctypes.c_ulonglong), ("used", ctypes.c_ulonglong)]

    def __init__(self):
        self.lib = ctypes.CDLL("libnvidia-ml.so.1")
        self.lib.nvmlInit_v2()
        self.handle = ctypes.c_void_p()
        self.lib.nvmlDeviceGetHandleByIndex_v2(0, ctypes.byref(self.handle))

    def __call__(self) -> int:
        info = self._Info()
        self.lib.nvmlDeviceGetMemoryInfo(self.handle, ctypes.byref(info))
        return int(info.used)


def _rss() -> int:
    import psutil

    return psutil.Process().memory_info().rss


def _reset_high_water() -> bool:
    """The kernel's peak resident set of this process (Linux's VmHWM) reset to the present
    one; False where it cannot be."""
    try:
        with open("/proc/self/clear_refs", "w") as f:
            f.write("5")
        return True
    except OSError:
        return False


def _high_water() -> int:
    """The kernel's peak resident set of this process since its last reset, in bytes."""
    with open("/proc/self/status") as f:
        return next(int(line.split()[1]) * 1024 for line in f if line.startswith("VmHWM:"))


class Peak:
    """The largest reading of `used` while the block runs, polled every millisecond; with
    high_water (`used` the resident set), the kernel's own peak too where it can be read, which
    counts what lasts less than a poll's millisecond or comes while the poll waits for the GIL."""

    def __init__(self, used, high_water: bool = False):
        self.used, self.peak, self._stop = used, 0, threading.Event()
        self._high_water = high_water

    def __enter__(self):
        self._high_water = self._high_water and _reset_high_water()
        self.peak = self.used()
        self._thread = threading.Thread(target=self._poll, daemon=True)
        self._thread.start()
        return self

    def _poll(self):
        while not self._stop.wait(0.001):
            self.peak = max(self.peak, self.used())

    def __exit__(self, *exc):
        self._stop.set()
        self._thread.join(timeout=5.0)
        self.peak = max(self.peak, self.used())
        if self._high_water:
            self.peak = max(self.peak, _high_water())


def memory_mesh(n: int, kind: str) -> Mesh:
    """The memory frame's mesh: n random triangles, or the icosphere of n triangles."""
    return random_triangles(n) if kind == "random" else icosphere(round(math.log(n / 20, 4)))


def warm_up(device: str, kind: str, basis) -> None:
    """A frame of a small mesh of the memory frame's kind, untimed, so that the kernels are compiled
    or loaded (and a GPU's context made) before the peak is watched. Over sah_steps.WIDE triangles,
    so that the builder's way for many is compiled too: its compile's memory (LLVM's) was counted
    in the cpu's peak until 2026-12-05. Read as the large mesh will be (triangle_mesh.read_through:
    the cpu reads a large icosphere through the tree's order): until 2026-12-06, later, the
    icosphere's kernels were loaded in the peak."""
    width, height = SIZE
    small = Painted(random_triangles(2 * WIDE) if kind == "random" else icosphere(5), MESH_COLOUR)
    floor = getattr(triangle_mesh, "INDEXED_FROM", None)  # a version without it reads no mesh so
    if floor is not None and kind != "random":
        triangle_mesh.INDEXED_FROM = 0
    try:
        with backends.tracer(device, small, width, height, primitive="triangle") as warm:
            warm.compile()
            warm.trace(basis)
    finally:
        if floor is not None:
            triangle_mesh.INDEXED_FROM = floor


def memory(n: int, device: str, frames: int, kind: str = "random") -> dict:
    """A frame of n triangles on device (random ones, or an icosphere's), with the memory it took
    beyond the mesh."""
    width, height = SIZE
    basis = Camera(position=(0.0, 0.0, -3.0), look_at=(0.0, 0.0, 0.0), fov_deg=60.0).basis(width, height)
    warm_up(device, kind, basis)
    mesh = memory_mesh(n, kind)
    own = mesh.vertices.nbytes + mesh.faces.nbytes
    used = _Nvml() if device == "cuda" else _rss
    # what the mesh's making let go (trimesh's objects hold cycles) collected now, not in the
    # middle of the frame's making, where it would offset what the frame takes
    gc.collect()
    before = used()
    frames_ms = []
    with Peak(used, high_water=device == "cpu") as peak:
        start = time.perf_counter()
        # the mesh and its colour: each device makes what it traces from them (meshes.Painted)
        tracer = backends.tracer(device, Painted(mesh, MESH_COLOUR), width, height, primitive="triangle")
        made_s = time.perf_counter() - start
        try:
            tracer.trace(basis)
            for _ in range(frames):
                start = time.perf_counter()
                tracer.trace(basis)
                frames_ms.append((time.perf_counter() - start) * 1e3)
            build_s = tracer.build_s
        finally:
            tracer.close()
    extra = peak.peak - before
    values = {"peak_extra_bytes": extra, "mesh_bytes": own, "extra_over_mesh": round(extra / own, 3),
              "build_s": build_s, "tracer_s": made_s}  # fmt: skip
    return _harness.part("mesh-memory", device, frames_ms, width=width, height=height,
                         options=options(f"{kind} {n}", n, measured="nvml used" if device == "cuda" else "rss, VmHWM"),
                         values=values)  # fmt: skip


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--device", action="append", choices=("cuda", "wgpu"), help="GPU builds (default cuda)")
    parser.add_argument("--subdivisions", action="append", type=int, help="icosphere subdivisions")
    parser.add_argument("--random", action="append", type=int, help="random triangles")
    parser.add_argument("--quality", action="append", help="the GPU tree's quality (default sah)")
    parser.add_argument("--repeats", type=int, default=21, help="timed GPU builds per mesh")
    parser.add_argument("--memory", type=int, default=0, help="triangles of the memory frame (0: none)")
    parser.add_argument("--memory-device", action="append", choices=("cpu", "cuda"), help="default cuda")
    parser.add_argument("--memory-mesh", choices=("random", "icosphere"), default="random",
                        help="the memory frame's mesh (icosphere: N must be 20 x 4^k)")  # fmt: skip
    _harness.add_common(parser, frames=5)
    args = parser.parse_args()
    _harness.check_common(parser, args)
    if args.memory and "cpu" in (args.memory_device or []):
        _harness.own_pages()  # the resident set counts every large array
    if (
        args.memory
        and args.memory_mesh == "icosphere"
        and 20 * 4 ** round(math.log(args.memory / 20, 4)) != args.memory
    ):
        parser.error(f"--memory {args.memory}: an icosphere has 20 x 4^k triangles")
    with _harness.Records("mesh_build", args, {}) as out:
        for name, mesh in meshes(args):
            for record in builds(name, mesh, args):
                out.write(record)
        if args.memory:
            for device in args.memory_device or ["cuda"]:
                out.write(memory(args.memory, device, args.frames, args.memory_mesh))
    return 0


if __name__ == "__main__":
    sys.exit(main())
