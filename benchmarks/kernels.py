"""The kernels against the hardware: measured FP32 peak of each processor, the simple and fast
kernels side by side on the same frame (their images must be identical on the CPU; on a GPU the
compiler may fuse multiply-adds differently in the two kernels), and a sweep of the CUDA fast
kernel's shape. Records of the results schema: the peaks in the "parts" suite (quantity
"fp32-peak", the measurement's time with its GFLOP/s), the kernels in the "scaling" suite (accel
"none", each kernel; the fast kernel's record says whether its picture is the simple one's), the
sweep in the "parts" suite (quantity "fast-kernel-shape": the kernel's time, a shape each).

    python benchmarks/kernels.py --out kernels.jsonl [--frames 7] [--sweep | --sweep-trip]

The figures in docs/notes/floors.md come from this script.
"""

import argparse
import sys

import _harness
import numpy as np

import raybench
from raybench import backends
from raybench.bench import peak


def frames(tracer, basis, n):
    """Whole-frame ms and kernel ms (None on the CPU) of n warm frames."""
    tracer.trace(basis)
    walls, kernels = [], []
    for _ in range(n):
        walls.extend(_harness.timings(lambda: kernels.append(tracer.timed_trace(basis)), 1))
    return walls, (kernels if kernels[0] is not None else None)


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--size", default="1680x1050")
    ap.add_argument("--spheres", type=int, default=1000)
    ap.add_argument("--sweep", action="store_true", help="the CUDA fast kernel's rays, spheres staged and block shapes")
    ap.add_argument("--sweep-trip", action="store_true", help="its spheres per trip of the cull loop")
    ap.add_argument("--skip-peak", action="store_true")
    _harness.add_common(ap, frames=7)
    args = ap.parse_args()
    _harness.check_common(ap, args)
    w, h = map(int, args.size.split("x"))
    # wgpu has the simple kernel alone: nothing to set side by side here
    devices = [d for d in backends.present() if d != "wgpu"]
    with _harness.Records("kernels", args, {"sweep": args.sweep, "sweep_trip": args.sweep_trip}) as out:
        if not args.skip_peak:
            for device, measure in (("cpu", peak.cpu_peak), ("cuda", peak.cuda_peak)):
                if device in devices:
                    got = []
                    times = _harness.timings(lambda m=measure, into=got: into.append(m()), 1)
                    out.write(_harness.part("fp32-peak", device, times, values={"fp32_gflops": got[0]["fp32_gflops"]}))
        scene = raybench.random_spheres(args.spheres, seed=0)
        basis = raybench.Camera().basis(w, h)
        for device in devices:
            images = {}
            for kernel in ("simple", "fast"):
                tracer = backends.tracer(device, scene.spheres, w, h, kernel=kernel)
                compile_s = tracer.compile()
                wall, kern = frames(tracer, basis, args.frames)
                images[kernel] = (tracer.image.copy(), tracer.hits.copy())
                record = _harness.point(
                    "scaling", device, w, h, args.spheres, {"accel": "none", "kernel": kernel}, wall, kern,
                    compile_s=compile_s,
                )  # fmt: skip
                record["tests_per_s"] = (
                    args.spheres * w * h / ((record["kernel_ms"] or record["frame_ms"])["median"] / 1e3)
                )
                if kernel == "fast":
                    (img_s, hits_s), (img_f, hits_f) = images["simple"], images["fast"]
                    diff = np.abs(img_s.astype(int) - img_f.astype(int))
                    record["against_simple"] = {
                        "images_identical": bool(np.array_equal(img_s, img_f)),
                        "hits_differing": int((hits_s != hits_f).sum()),
                        "pixels_differing": int(diff.max(axis=2).astype(bool).sum()),
                        "max_colour_step": int(diff.max()),
                    }
                out.write(record)
                tracer.close()
        if (args.sweep or args.sweep_trip) and "cuda" in devices:
            if args.sweep:
                shapes = [
                    (rays, staged, 2, block)
                    for rays in (1, 2, 4, 8, 16)
                    for staged in (128, 256, 512)
                    for block in ((32, 2), (16, 4), (32, 4), (32, 8), (16, 16), (64, 4), (128, 1))
                ]
            else:  # spheres per trip of the cull loop, around the default shape, twice over
                shapes = [
                    (8, 256, trip, block)
                    for _ in range(2)
                    for trip in (1, 2, 3, 4)
                    for block in ((16, 4), (32, 2), (8, 8))
                ]
            for rays, staged, trip, block in shapes:
                tracer = backends.tracer("cuda", scene.spheres, w, h, rays=rays, staged=staged, trip=trip, block=block)
                tracer.compile()
                _wall, kern = frames(tracer, basis, args.frames)
                tracer.close()
                options = {"rays": rays, "staged": staged, "trip": trip, "block": list(block)}
                median = sorted(kern)[len(kern) // 2]
                out.write(
                    _harness.part(
                        "fast-kernel-shape", "cuda", kern, spheres=args.spheres, width=w, height=h, options=options,
                        values={"tests_per_s": w * h * args.spheres / (median / 1e3)},
                    )
                )  # fmt: skip
    return 0


if __name__ == "__main__":
    sys.exit(main())
