"""Frames of several versions side by side: each version's frames traced in a process of its own
(its `raybench` package first on PYTHONPATH, its own compile cache, filled by an untimed run
first), the versions taking turns round by round, so that a slow spell of the machine falls on
every version alike. One record of the results schema's "parts" suite (quantity "frame") a
version and sphere count, the frames of all its rounds together, options naming the version.

    python benchmarks/versions_paired.py --version base=base-e0f68db/src --version new=src \\
        --spheres 1000 --spheres 100000 --size 840x525 --device cpu --rounds 5

Only the public API of raybench (Renderer, random_spheres, Camera) is used in the children, so
any version since the Renderer can be measured. The thesis's shading unless --shading whitted.
"""

import argparse
import json
import os
import subprocess
import sys
import tempfile

import _harness

CHILD = """
import json, sys, time
import raybench
n, w, h, frames, device, shading, threads, clock, accel = json.loads(sys.argv[1])
clock = getattr(time, clock)
options = {"threads": threads} if threads else {}
if accel:
    options["accel"] = accel
scene = raybench.random_spheres(n, seed=0, materials=shading == "whitted")
with raybench.Renderer(scene, w, h, device=device, shading=shading, **options) as renderer:
    camera = raybench.Camera()
    renderer.render(camera)
    times = []
    for _ in range(frames):
        start = clock()
        renderer.render(camera)
        times.append((clock() - start) * 1e3)
print(json.dumps(times))
"""


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--version", action="append", required=True, help="NAME=DIR (DIR holds its raybench)")
    parser.add_argument("--spheres", action="append", type=int)
    parser.add_argument("--size", default="840x525")
    parser.add_argument("--device", default="cpu")
    parser.add_argument("--shading", default="thesis", choices=["thesis", "whitted"])
    parser.add_argument("--threads", type=int)
    parser.add_argument("--accel", choices=["bvh", "none"], help="default: the Renderer's (the BVH)")
    parser.add_argument(
        "--clock",
        default="perf_counter",
        choices=["perf_counter", "process_time"],
        help="a frame's wall time (default), or the CPU time of all the process's threads: on a machine that "
        "others load, what the frame's own work costs",
    )
    _harness.add_common(parser, frames=5, rounds=5)
    args = parser.parse_args()
    _harness.check_common(parser, args)
    versions = dict(v.split("=", 1) for v in args.version)
    width, height = (int(v) for v in args.size.split("x"))
    counts = args.spheres or [1000, 100_000]
    settings = {"versions": args.version, "size": args.size, "shading": args.shading, "frames": args.frames,
                "clock": args.clock}  # fmt: skip
    path = os.environ.get("PYTHONPATH", "")
    with tempfile.TemporaryDirectory() as scratch, _harness.Records("versions_paired", args, settings) as records:

        def run(version: str, n: int, frames: int) -> list[float]:
            env = {
                **os.environ,
                "RAYBENCH_CACHE_DIR": os.path.join(scratch, version),
                "PYTHONPATH": os.pathsep.join(p for p in (os.path.abspath(versions[version]), path) if p),
            }
            given = [n, width, height, frames, args.device, args.shading, args.threads, args.clock, args.accel]
            given = json.dumps(given)
            done = subprocess.run(
                [sys.executable, "-c", CHILD, given], env=env, capture_output=True, text=True, check=True
            )
            return json.loads(done.stdout.strip().splitlines()[-1])

        for n in counts:
            for version in versions:
                run(version, n, 1)  # its compile cache filled, untimed
            times = {version: [] for version in versions}
            order = list(versions)
            for round_ in range(args.rounds):
                for version in order[round_ % len(order) :] + order[: round_ % len(order)]:
                    times[version] += run(version, n, args.frames)
            for version, samples in times.items():
                options = {"version": version, "shading": args.shading, "threads": args.threads, "accel": args.accel}
                if args.clock != "perf_counter":
                    options["clock"] = args.clock
                records.write(
                    _harness.part("frame", args.device, samples, spheres=n, width=width, height=height, options=options)
                )
    return 0


if __name__ == "__main__":
    sys.exit(main())
