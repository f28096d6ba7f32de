"""The CPU's packet walk on the binary SAH tree against the same tree
collapsed into 4-wide nodes (the cpu Tracer's tree_width, issue 16 item 6),
side by side in one process: a Tracer of each over the same scene, warm
frames, then --rounds rounds of --frames frames each, the two alternating
which goes first each round (a shared machine's load falls on both);
medians over every frame of each. One JSON line per (layout, spheres).

    PYTHONPATH=src python benchmarks/cpu_tree_width.py --spheres 1000 10000 100000 1000000
"""

import argparse
import json
import os
import statistics
import time
from datetime import UTC, datetime

import numpy as np

import raybench
from raybench import Camera
from raybench.backends import cpu
from raybench.host import usable_cores
from raybench.machine import cpu as processor
from raybench.machine import git_commit
from raybench.scene import SPREADS


def main():
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--spheres", type=int, nargs="+", default=[1000, 10_000, 100_000, 1_000_000])
    p.add_argument("--layouts", nargs="+", default=["even"], choices=SPREADS)
    p.add_argument("--size", default="1680x1050")
    p.add_argument("--rounds", type=int, default=5)
    p.add_argument("--frames", type=int, default=2)
    p.add_argument("--threads", type=int, default=None)
    p.add_argument("--label", default="")
    p.add_argument("--out")
    args = p.parse_args()
    width, height = (int(v) for v in args.size.split("x"))
    basis = Camera().basis(width, height)
    base = {
        "what": "cpu_tree_width",
        "date": datetime.now(UTC).isoformat(timespec="seconds"),
        "raybench_commit": git_commit(),
        "processor": processor(),
        "usable_cores": usable_cores(),
        "load_average": os.getloadavg(),
        "label": args.label,
    }
    for n in args.spheres:
        for layout in args.layouts:
            scene = raybench.random_spheres(n, 0, layout=layout)
            tracers = {}
            try:
                for w in (2, 4):
                    tracers[w] = cpu.Tracer(scene.spheres, width, height, threads=args.threads, tree_width=w)
                    tracers[w].compile()
                    for _ in range(2):
                        tracers[w].trace(basis)
                same = np.array_equal(tracers[2].hits, tracers[4].hits) and np.array_equal(
                    tracers[2].image, tracers[4].image
                )
                times = {2: [], 4: []}
                cpu_times = {2: [], 4: []}
                for r in range(args.rounds):
                    for w in (2, 4) if r % 2 == 0 else (4, 2):
                        for _ in range(args.frames):
                            start, start_cpu = time.perf_counter(), time.process_time()
                            tracers[w].trace(basis)
                            times[w].append(time.perf_counter() - start)
                            cpu_times[w].append(time.process_time() - start_cpu)
            finally:
                for t in tracers.values():
                    t.close()
            binary, wide = (statistics.median(times[w]) * 1e3 for w in (2, 4))
            record = {
                **base,
                "layout": layout,
                "spheres": n,
                "width": width,
                "height": height,
                "threads": tracers[2].threads,
                "binary_ms": binary,
                "wide_ms": wide,
                "speedup": binary / wide,
                "binary_rays_per_s": width * height / binary * 1e3,
                "wide_rays_per_s": width * height / wide * 1e3,
                # CPU time of the process a frame (all its threads): what a
                # neighbour's load on a shared machine inflates less
                "binary_cpu_ms": statistics.median(cpu_times[2]) * 1e3,
                "wide_cpu_ms": statistics.median(cpu_times[4]) * 1e3,
                "binary_frames_ms": [x * 1e3 for x in times[2]],
                "wide_frames_ms": [x * 1e3 for x in times[4]],
                "binary_build_s": tracers[2].build_s,
                "wide_build_s": tracers[4].build_s,
                "binary_nodes": len(tracers[2].bvh.nodes),
                "wide_nodes": len(tracers[4].wide),
                "same_picture": bool(same),
            }
            print(
                f"{layout:9s} {n:>9,}  binary {binary:8.2f} ms  wide {wide:8.2f} ms  x{binary / wide:.2f}  "
                f"cpu {record['binary_cpu_ms']:8.2f} / {record['wide_cpu_ms']:8.2f} ms  same {same}",
                flush=True,
            )
            if args.out:
                with open(args.out, "a") as f:
                    f.write(json.dumps(record) + "\n")


if __name__ == "__main__":
    main()
