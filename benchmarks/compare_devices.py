"""Render one scene on every device present and compare: identical hit indices,
colour differences, and warm frame times (median). A quick check, not the
benchmark: `raybench bench` measures properly.

    python benchmarks/compare_devices.py --spheres 1000 --size 1680x1050 --frames 20
"""

import argparse
import json
import statistics
import sys
import time
from pathlib import Path

import numpy as np

from raybench import Camera, backends, files, random_spheres
from raybench.cli import parse_size


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--spheres", type=int, default=1000)
    ap.add_argument("--size", default="1680x1050")
    ap.add_argument("--frames", type=int, default=20)
    ap.add_argument("--json")
    args = ap.parse_args()
    width, height = parse_size(args.size)
    scene = random_spheres(args.spheres, 0)
    basis = Camera().basis(width, height)
    results, frames = {}, {}
    for device in backends.present():
        tracer = backends.tracer(device, scene.spheres, width, height)
        start = time.perf_counter()
        image, hits = tracer.trace(basis)
        first = time.perf_counter() - start
        times = []
        for _ in range(args.frames):
            start = time.perf_counter()
            tracer.trace(basis)
            times.append(time.perf_counter() - start)
        frames[device] = (image.copy(), hits.copy())
        med = statistics.median(times)
        results[device] = {
            "first_frame_s": first,
            "median_frame_ms": med * 1e3,
            "rays_per_s": width * height / med,
            "tests_per_s": width * height * args.spheres / med,
        }
        print(
            f"{device:5s} first frame {first:7.2f} s, median warm frame {med * 1e3:9.2f} ms, "
            f"{width * height * args.spheres / med / 1e9:8.2f} G ray-sphere tests/s"
        )
    if "cuda" in frames:
        (ci, ch), (gi, gh) = frames["cpu"], frames["cuda"]
        diff = np.abs(ci.astype(int) - gi.astype(int)).max(axis=2)
        results["comparison"] = {
            "pixels": width * height,
            "hits_differ": int((ch != gh).sum()),
            "colour_differs": int((diff > 0).sum()),
            "max_colour_steps": int(diff.max()),
            "colour_differs_by_more_than_1_step": int((diff > 1).sum()),
        }
        # Where the devices disagree on the sphere, ask the float64 reference
        # whether rounding alone can decide it there.
        sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "tests"))
        from reference import trace

        differ = np.flatnonzero(ch != gh)
        ref = trace(scene, Camera(), width, height, pixels=differ)
        explained = [
            bool(ref.ambiguous[i]) and {int(ch.flat[p]), int(gh.flat[p])} <= ref.candidates.get(i, set())
            for i, p in enumerate(differ)
        ]
        results["comparison"]["hits_differ_where_float32_rounding_decides"] = int(sum(explained))
        results["comparison"]["differing_pixels"] = [
            {
                "x": int(p % width),
                "y": int(p // width),
                "cpu": int(ch.flat[p]),
                "cuda": int(gh.flat[p]),
                "reference": int(ref.hits[i]),
                "possible": sorted(ref.candidates.get(i, [])),
            }
            for i, p in enumerate(differ[:20])
        ]
        results["speedup_cuda_over_cpu"] = results["cpu"]["median_frame_ms"] / results["cuda"]["median_frame_ms"]
        print(json.dumps(results["comparison"]), f"speedup {results['speedup_cuda_over_cpu']:.1f}x")
    if args.json:
        record = {"spheres": args.spheres, "size": [width, height], "frames": args.frames, **results}
        files.write_atomic(args.json, json.dumps(record, indent=1).encode())


if __name__ == "__main__":
    main()
