"""Triangle meshes' first figures on each device, before a meshes suite exists: what a frame
of an icosphere costs, primary rays and Whitted's, with the tree built on the host or the GPU.

The workload is the one the triangle issue measured Mitsuba 3 on OptiX with: an icosphere of
radius 1 (trimesh.creation.icosphere), seen from (0, 0, -2) looking at its centre, a 60 degree
field of view, 1680x1050. Primary rays are the thesis's shading (|N.D| times the colour);
Whitted's are depth 5 with 4 shadow samples of one area-free point light, every triangle matte,
every ray the kernels cast counted.

Each (device, triangles, shading, build) is one tracer: built, compiled, a first frame and
--warm frames left out, then --frames frames timed by wall clock (a GPU's copy of the frame to
the host included, as every whole frame in raybench is). One JSON line a point, to stdout and
--out, with the machine and the commit (RAYBENCH_GIT_COMMIT or git).

    PYTHONPATH=src python benchmarks/archive/mesh_first_figures.py --device cuda --device wgpu \\
        --subdivisions 6 --subdivisions 8 --out mesh.jsonl
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np
import trimesh

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))  # _harness, beside benchmarks/archive
import _harness

from raybench import backends
from raybench.camera import Camera
from raybench.layout import KINDS as RAY_KINDS
from raybench.lighting import Light, Shading
from raybench.meshes import Mesh
from raybench.scene import Scene
from raybench.scene_meshes import SceneMesh

SIZE = (1680, 1050)


def icosphere(subdivisions: int) -> Scene:
    m = trimesh.creation.icosphere(subdivisions=subdivisions, radius=1.0)
    mesh = Mesh(np.asarray(m.vertices, np.float32), np.asarray(m.faces, np.int32), None)
    camera = Camera(position=(0.0, 0.0, -2.0), look_at=(0.0, 0.0, 0.0), fov_deg=60.0)
    light = Light(position=(-2.0, 3.0, -3.0))
    return Scene([], [], [], camera, lights=(light,), meshes=[SceneMesh(mesh)])


def measure(scene: Scene, device: str, shading: str, build: str, args) -> dict:
    width, height = SIZE
    shaded = Shading.of(scene, args.depth, args.shadow_samples) if shading == "whitted" else None
    options = {"build": build} if device != "cpu" else {}
    start = time.perf_counter()
    tracer = backends.tracer(device, scene.triangles, width, height, shaded, primitive="triangle", **options)
    made_s = time.perf_counter() - start
    basis = scene.camera.basis(width, height)
    try:
        compile_s = tracer.compile()
        start = time.perf_counter()
        image, hits = tracer.trace(basis)
        first_s = time.perf_counter() - start
        for _ in range(args.warm):
            tracer.trace(basis)
        frames = []
        for _ in range(args.frames):
            start = time.perf_counter()
            tracer.trace(basis)
            frames.append((time.perf_counter() - start) * 1e3)
        counts = None if tracer.ray_counts is None else [int(c) for c in tracer.ray_counts]
        hit_share = float(np.mean(np.asarray(hits) >= 0))
        build_s = tracer.build_s
    finally:
        tracer.close()
    median = float(np.median(frames))
    rays = sum(counts) if counts else width * height
    values = {
        "rays_per_frame": rays,
        "rays_per_s": rays / (median / 1e3),
        "hit_share": hit_share,
        "build_s": build_s,
        "tracer_s": made_s,
        "compile_s": compile_s,
        "first_frame_s": first_s,
        **({f"{kind}_rays": count for kind, count in zip(RAY_KINDS, counts)} if counts else {}),
    }
    return as_part(device, scene.triangles.shape[1], shading, build, frames, values)


def as_part(device: str, triangles: int, shading: str, build: str, frames_ms: list, values: dict) -> dict:
    """One point as a record of the results schema's "parts" suite."""
    options = {"primitive": "triangle", "triangles": triangles, "shading": shading, "build": build}
    return _harness.part("mesh-frame", device, frames_ms, width=SIZE[0], height=SIZE[1], options=options,
                         values=values)  # fmt: skip


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--device", action="append", help="cpu, cuda or wgpu; repeat (default cpu)")
    parser.add_argument("--subdivisions", action="append", type=int, help="icosphere subdivisions (default 6 and 8)")
    parser.add_argument("--shading", action="append", choices=("thesis", "whitted"), help="default both")
    parser.add_argument("--build", action="append", choices=("host", "gpu"), help="GPUs' trees (default host)")
    parser.add_argument("--warm", type=int, default=2)
    parser.add_argument("--depth", type=int, default=5)
    parser.add_argument("--shadow-samples", type=int, default=4)
    _harness.add_common(parser, frames=9)
    args = parser.parse_args()
    _harness.check_common(parser, args)
    with _harness.Records("archive/mesh_first_figures", args, {"warm": args.warm}) as out:
        for subdivisions in args.subdivisions or [6, 8]:
            scene = icosphere(subdivisions)
            for device in args.device or ["cpu"]:
                for shading in args.shading or ["thesis", "whitted"]:
                    for build in (args.build or ["host"]) if device != "cpu" else ["host"]:
                        out.write(measure(scene, device, shading, build, args))
    return 0


if __name__ == "__main__":
    sys.exit(main())
