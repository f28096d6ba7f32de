"""The icosphere of 1.31 M triangles (bench.meshes.mesh_scene), primary rays on cuda at
1680x1050, for one version of raybench (its src first on PYTHONPATH): the medians of N frames'
kernels (timed_trace) and whole frames, the walk, the shape of the scene's buffer on the device,
and the last picture and hits saved to OUT.npz for comparing two versions' frames pixel by pixel.

    PYTHONPATH=<src> python benchmarks/archive/mesh_primary_gpu.py NAME OUT.npz 9

Run in turn for the versions compared. The figures: benchmarks/results/h100/triangles/README.md.
"""

import json
import sys

import numpy as np
from mesh_frames_gpu import timed

import raybench
from raybench.bench import meshes


def main(name: str, out: str, frames: int) -> None:
    scene = meshes.mesh_scene("icosphere", 1310720)
    with raybench.Renderer(scene, 1680, 1050, "cuda", "thesis") as renderer:
        kernel_ms, whole_ms, frame = timed(renderer, scene.camera, frames)
        np.savez(out, image=frame.image, hits=frame.hits)
        tracer = renderer.tracer
        print(json.dumps({"version": name, "walk": tracer.walk, "rows": list(tracer.d_spheres.shape),
                          "kernel_ms": kernel_ms, "whole_ms": whole_ms}))  # fmt: skip


if __name__ == "__main__":
    main(sys.argv[1], sys.argv[2], int(sys.argv[3]))
