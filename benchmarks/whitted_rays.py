"""Whitted shading's throughput: one record of the results schema (suite "secondary", shading
"whitted") per (device, spheres, accel): the issue's scene (random_spheres(n, materials=True):
mixed materials, one area light), depth 5, 4 shadow samples, 1680x1050 by default; with
--icosphere N, the meshes suite's icosphere of N triangles instead (bench.meshes.mesh_scene: matte,
one light of radius 0.5, its own camera), made as a program makes it (raybench.Renderer). The frames'
times and the kernel's own (CUDA events, wgpu GPU timestamps), the rays the kernel counted by
kind, and rays a second with every kind counted. `raybench report` reads them.

For A/B runs of two versions, as bvh_walks.py: PYTHONPATH=old/src, then src, each with its --label.
"""

import argparse
import inspect
import json
import sys
import time

import _harness

import raybench
from raybench import Camera, RaybenchError, backends, lighting

# backends.tracer's keyword for the Shading: "shading", or "whitted" in a
# baseline's raybench before issue 36 (gpu_lease.sh runs this file on both)
SHADING = "shading" if "shading" in inspect.signature(backends.tracer).parameters else "whitted"


def one(device, spheres, width, height, frames, accel, depth, samples, block=None, schedule=None, wave_grid=None,
        tree_width=None, mesh=False):  # fmt: skip
    options = {"cuda": {"block": block}, "wgpu": {"workgroup": block}}.get(device, {}) if block else {}
    if schedule is not None:
        options["schedule"] = schedule
    if wave_grid is not None and schedule == "wavefront" and device == "cuda":
        options["wave_grid"] = wave_grid
    if tree_width is not None:
        options["tree_width"] = tree_width
    if mesh:
        renderer, basis = _mesh_renderer(device, spheres, width, height, accel, depth, samples, options)
        with renderer:
            return _measured(renderer.tracer, basis, device, spheres, width, height, frames, accel, depth, samples,
                             schedule, options, {"mesh": "icosphere", "triangles": spheres})  # fmt: skip
    scene = raybench.random_spheres(spheres, seed=0, materials=True)
    shading = lighting.Shading.of(scene, depth, samples)
    basis = Camera().basis(width, height)
    options[SHADING] = shading
    with backends.tracer(device, scene.spheres, width, height, accel=accel, **options) as tracer:
        return _measured(tracer, basis, device, spheres, width, height, frames, accel, depth, samples, schedule,
                         options)  # fmt: skip


def _mesh_renderer(device, triangles, width, height, accel, depth, samples, options):
    """The meshes suite's icosphere point made as the suite makes it (raybench.Renderer, with the
    tracer's options), and its camera's basis."""
    from raybench.bench import meshes

    scene = meshes.mesh_scene("icosphere", triangles)
    renderer = raybench.Renderer(scene, width, height, device, "whitted", depth, samples, accel=accel, **options)
    return renderer, scene.camera.basis(width, height)


def _measured(tracer, basis, device, spheres, width, height, frames, accel, depth, samples, schedule, options,
              scene=None):  # fmt: skip
    """One point's record from a made tracer: the first frame, then `frames` timed ones; scene: the
    options that name a mesh's scene (the record's spheres are then its triangles)."""
    wave_grid = options.get("wave_grid")
    start = time.perf_counter()
    tracer.trace(basis)  # compiled, uploaded
    first_s = time.perf_counter() - start
    kernel, whole = [], []
    for _ in range(frames):
        start = time.perf_counter()
        kernel_ms = tracer.timed_trace(basis)
        whole.append((time.perf_counter() - start) * 1e3)
        kernel.append(kernel_ms if kernel_ms is not None else whole[-1])
    rays = dict(zip(("primary", "shadow", "reflection", "refraction"), tracer.ray_counts.tolist()))
    total = sum(rays.values())
    timed = kernel_ms is not None  # the last frame's: whether the device times its kernel
    used = {**(scene or {}), "accel": accel, "shading": "whitted", "depth": depth, "shadow_samples": samples}
    if schedule is not None:
        used["schedule"] = schedule
    if "wave_grid" in options:
        used["wave_grid"] = wave_grid
    if getattr(tracer.options, "tree_width", None) is not None:
        used["tree_width"] = tracer.options.tree_width
    shape = getattr(tracer, "block", None) or getattr(tracer, "workgroup", None)
    if shape is not None:
        used["block"] = list(shape)
    if getattr(tracer, "threads", None) is not None:
        used["threads"] = tracer.threads
    record = _harness.point(
        "secondary", device, width, height, spheres, used, whole, kernel if timed else None,
        first_frame_s=first_s, compile_s=None, build_s=getattr(tracer, "build_s", None),
        rays=rays, rays_per_frame=total,
    )  # fmt: skip
    record["rays_per_s"] = total / (record["frame_ms"]["median"] / 1e3)
    record["kernel_rays_per_s"] = total / (record["kernel_ms"]["median"] / 1e3) if timed else None
    record.update(_resources(tracer))
    record["raybench"] = raybench.__file__  # which source tree ran (A/B runs)
    return record


def _resources(tracer) -> dict:
    """cuda: each Whitted kernel's registers and local memory a thread (spills
    and the stacks), by kernel (the frame's, or the wavefront's stages);
    other devices: nothing."""
    if tracer.name != "cuda":
        return {}
    out = {}
    for name, kernel in tracer.kernels().items():
        try:
            (signature,) = kernel.overloads.keys()
            out[f"regs_{name}"] = kernel.get_regs_per_thread(signature)
            out[f"local_bytes_{name}"] = kernel.get_local_mem_per_thread(signature)
        except Exception as exc:  # noqa: BLE001 - a numba-cuda without the query: the record says so
            out[f"resources_{name}"] = f"unknown ({exc.__class__.__name__})"
    return out


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--device", action="append", choices=["cpu", "cuda", "wgpu"])
    parser.add_argument("--spheres", action="append", type=int)
    parser.add_argument("--accel", action="append", choices=["bvh", "none"])
    parser.add_argument("--size", default="1680x1050")
    parser.add_argument("--depth", type=int, default=5)
    parser.add_argument("--shadow-samples", type=int, default=4)
    parser.add_argument(
        "--block",
        type=int,
        nargs=2,
        action="append",
        metavar=("X", "Y"),
        help="cuda's block, wgpu's workgroup; each in turn",
    )
    parser.add_argument(
        "--icosphere", action="append", type=int, help="triangles: the meshes suite's icosphere, not spheres"
    )
    parser.add_argument(
        "--schedule", action="append", choices=["wavefront", "pixel"], help="cuda, wgpu: how Whitted's rays go"
    )
    parser.add_argument("--wave-grid", type=int, help="cuda's wavefront: blocks a stage (default: 32 a multiprocessor)")
    parser.add_argument(
        "--tree-width",
        action="append",
        type=int,
        choices=[2, 4],
        help="cpu: the tree its BVH packets and bounces walk (2 or 4); each in turn",
    )
    _harness.add_common(parser, frames=7)
    args = parser.parse_args()
    _harness.check_common(parser, args)
    width, height = (int(v) for v in args.size.split("x"))
    settings = {"size": args.size, "depth": args.depth, "shadow_samples": args.shadow_samples, "frames": args.frames}
    if args.icosphere and args.spheres:
        parser.error("--icosphere and --spheres: one scene or the other")
    counts = args.icosphere or args.spheres or [1000, 10_000, 100_000]
    with _harness.Records("whitted_rays", args, settings) as out:
        for _ in range(args.rounds):
            for device in args.device or ["cuda"]:
                schedules = (args.schedule or [None]) if device in ("cuda", "wgpu") else [None]
                widths = args.tree_width or [None]
                for accel, schedule, tree_width in (
                    (a, s, w) for a in args.accel or ["bvh"] for s in schedules for w in widths
                ):
                    for n, block in ((n, b) for n in counts for b in args.block or [None]):
                        try:
                            out.write(one(device, n, width, height, args.frames, accel, args.depth,
                                          args.shadow_samples, tuple(block) if block else None, schedule,
                                          args.wave_grid, tree_width, mesh=bool(args.icosphere)))  # fmt: skip
                        except RaybenchError as exc:  # the point is not measured: said on stderr, the run goes on
                            print(
                                json.dumps({"device": device, "accel": accel, "spheres": n, "error": str(exc)}),
                                file=sys.stderr,
                            )
    return 0


if __name__ == "__main__":
    sys.exit(main())
