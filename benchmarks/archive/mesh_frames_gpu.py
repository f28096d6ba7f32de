"""A mesh's frames on a GPU device for one version of raybench (its `src/` first on PYTHONPATH):
the meshes suite's scenes (bench.meshes.mesh_scene: an icosphere, random triangles), 1680x1050,
primary rays (the thesis's shading) and Whitted's (depth 5, 4 shadow samples), each the median
of N frames of the kernels' own time (timed_trace) and of the whole frame (render), with hashes
of the picture and the hits, which must be the same in every version. One JSON line a version.

    PYTHONPATH=<its src> python benchmarks/archive/mesh_frames_gpu.py NAME --frames 21 \\
        --icosphere 81920 1310720 --random 1000000 --device cuda

Run in turn for the versions compared, two rounds (the figures: docs/triangles.md#memory).
"""

import argparse
import hashlib
import json
import statistics
import time

import raybench
from raybench.bench import meshes


def timed(renderer, camera, frames):
    """A warm Renderer's frames from camera: (the medians of `frames` kernels' own times, None
    where the tracer times none, and of whole frames, in ms; the last frame)."""
    width, height = renderer.width, renderer.height
    frame = renderer.render(camera)
    kernels, whole = [], []
    for _ in range(frames):
        start = time.perf_counter()
        frame = renderer.render(camera)
        whole.append((time.perf_counter() - start) * 1e3)
        kernel = renderer.tracer.timed_trace(camera.basis(width, height))
        if kernel is not None:
            kernels.append(kernel)
    kernel_ms = round(statistics.median(kernels), 4) if kernels else None
    return kernel_ms, round(statistics.median(whole), 4), frame


def _frames(scene, device, shading, frames):
    whitted = (5, 4) if shading == "whitted" else ()  # depth, shadow samples
    with raybench.Renderer(scene, 1680, 1050, device, shading, *whitted) as renderer:
        kernel_ms, whole_ms, frame = timed(renderer, scene.camera, frames)
        digest = hashlib.sha256(frame.image.tobytes() + frame.hits.tobytes()).hexdigest()[:12]
        return {"kernel_ms": kernel_ms, "whole_ms": whole_ms, "picture": digest}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("name")
    parser.add_argument("--frames", type=int, default=21)
    parser.add_argument("--icosphere", type=int, nargs="*", default=[81_920, 1_310_720])
    parser.add_argument("--random", type=int, nargs="*", default=[1_000_000])
    parser.add_argument("--device", default="cuda")
    parser.add_argument("--shading", nargs="+", default=["thesis", "whitted"])
    args = parser.parse_args()
    out = {}
    points = [("icosphere", n) for n in args.icosphere] + [("random", n) for n in args.random]
    for kind, n in points:
        scene = meshes.mesh_scene(kind, n)
        for shading in args.shading:
            out[f"{kind} {n} {shading}"] = _frames(scene, args.device, shading, args.frames)
    print(json.dumps({"version": args.name, "device": args.device, "frames": out}))


if __name__ == "__main__":
    main()
