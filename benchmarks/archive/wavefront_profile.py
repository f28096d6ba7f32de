"""A few cuda wavefront frames of the issue's scene, for a profiler to attach to (Nsight Compute:
`ncu --kernel-name regex:"_extend|_shadow" ... python3 benchmarks/archive/wavefront_profile.py`). It
traces --frames frames of random_spheres(--spheres, materials=True) at 1680x1050, depth 5, 4 shadow
samples, and prints their ray counts. Needs a CUDA GPU.
"""

import argparse
import sys

import raybench
from raybench import Camera, backends, lighting


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--spheres", type=int, default=10_000)
    parser.add_argument("--frames", type=int, default=2)
    args = parser.parse_args()
    scene = raybench.random_spheres(args.spheres, seed=0, materials=True)
    shading = lighting.Shading.of(scene, 5, 4)
    with backends.tracer("cuda", scene.spheres, 1680, 1050, whitted=shading) as tracer:
        for _ in range(args.frames):
            tracer.trace(Camera().basis(1680, 1050))
        print(dict(zip(("primary", "shadow", "reflection", "refraction"), tracer.ray_counts.tolist())))
    return 0


if __name__ == "__main__":
    sys.exit(main())
