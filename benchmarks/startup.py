"""Time to the first picture, in fresh processes: `import raybench`, then
`raybench render` cold (an empty compile cache: a new RAYBENCH_CACHE_DIR)
and warm (the cache the cold runs filled), each a median of --runs. One line
of JSON per measurement.

    python benchmarks/startup.py --device cpu --size 1680x1050 --spheres 1000
    python benchmarks/startup.py --device cpu --shading whitted
    python benchmarks/startup.py --device cuda --build gpu

The first line says what ran: the commit ($RAYBENCH_GIT_COMMIT where set),
where raybench was imported from, and the machine: its processor and the
cores this process may use (run it under `taskset -c 0,1` to time two).
"""

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time


def timed(command: list[str], env: dict, said: list | None = None) -> float:
    """The seconds command took; what it printed goes on `said` where given."""
    start = time.perf_counter()
    ran = subprocess.run(command, env=env, check=True, stdout=subprocess.PIPE, text=True)
    took = time.perf_counter() - start
    if said is not None:
        said.append(ran.stdout.strip())
    return took


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--device", action="append", choices=["cpu", "cuda", "wgpu"])
    parser.add_argument("--size", default="1680x1050")
    parser.add_argument("--spheres", type=int, default=1000)
    parser.add_argument("--shading", default="thesis", choices=["thesis", "whitted"])
    parser.add_argument("--runs", type=int, default=3)
    parser.add_argument("--build", choices=["host", "gpu"], help="render's --build (cuda): where the BVH is built")
    args = parser.parse_args()
    python = sys.executable
    describe = (
        "import json, os, raybench, raybench.machine as m; "
        "print(json.dumps({'what': 'run', 'git_commit': m.git_commit(), 'raybench': raybench.__file__, "
        "'cpu': m.describe()['cpu'], 'usable_cores': len(os.sched_getaffinity(0))}))"
    )
    ran = subprocess.run([python, "-c", describe], check=True, capture_output=True, text=True)
    print(ran.stdout.strip(), flush=True)
    with tempfile.TemporaryDirectory() as scratch:
        out = os.path.join(scratch, "x.png")
        base_env = dict(os.environ)
        imports = [timed([python, "-c", "import raybench"], base_env) for _ in range(args.runs)]
        print(json.dumps({"what": "import raybench", "median_s": round(statistics.median(imports), 3)}), flush=True)
        for device in args.device or ["cpu"]:
            render = [python, "-m", "raybench", "render", "--spheres", str(args.spheres), "--size", args.size,
                      "--device", device, "--shading", args.shading, "-o", out]  # fmt: skip
            if args.shading == "whitted":
                render.insert(render.index("--spheres") + 2, "--materials")
            if args.build:
                render += ["--build", args.build]
            # what render printed: its own time to the written picture, before the process ends
            cold, warm, said = [], [], {"cold": [], "warm": []}
            for run in range(args.runs):
                env = {**base_env, "RAYBENCH_CACHE_DIR": os.path.join(scratch, f"cold-{device}-{run}")}
                cold.append(timed(render, env, said["cold"]))
            warm_env = {**base_env, "RAYBENCH_CACHE_DIR": os.path.join(scratch, f"cold-{device}-0")}
            warm = [timed(render, warm_env, said["warm"]) for _ in range(args.runs)]
            for what, times in (("cold", cold), ("warm", warm)):
                row = {"what": f"render {what}", "device": device, "shading": args.shading, "spheres": args.spheres,
                       "size": args.size, "build": args.build, "median_s": round(statistics.median(times), 3),
                       "runs_s": [round(t, 3) for t in times], "said": said[what]}  # fmt: skip
                print(json.dumps(row), flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
