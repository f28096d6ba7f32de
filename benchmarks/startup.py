"""Time to the first picture, in fresh processes: `import raybench`, then
`raybench render` cold (an empty compile cache: a new RAYBENCH_CACHE_DIR)
and warm (the cache the cold runs filled), each --frames runs. One record of
the results schema's "parts" suite per measurement (quantity "import",
"startup-cold", "startup-warm").

    python benchmarks/startup.py --device cpu --size 1680x1050 --spheres 1000
    python benchmarks/startup.py --device cpu --shading whitted
    python benchmarks/startup.py --device cuda --build gpu

Each record's run says what ran: the commit ($RAYBENCH_GIT_COMMIT where set),
where raybench was imported from, and the machine; its usable_cores value the
cores this process may use (run it under `taskset -c 0,1` to time two).
"""

import argparse
import os
import subprocess
import sys
import tempfile

import _harness

from raybench.cli import parse_size
from raybench.host import usable_cores


def timed(command: list[str], env: dict) -> float:
    """The ms command took, to the end of its process."""
    return _harness.timings(lambda: subprocess.run(command, env=env, check=True, stdout=subprocess.DEVNULL), 1)[0]


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--device", action="append", choices=["cpu", "cuda", "wgpu"])
    parser.add_argument("--size", default="1680x1050")
    parser.add_argument("--spheres", type=int, default=1000)
    parser.add_argument("--shading", default="thesis", choices=["thesis", "whitted"])
    parser.add_argument("--build", choices=["host", "gpu"], help="render's --build (cuda): where the BVH is built")
    _harness.add_common(parser, frames=3)
    parser.add_argument("--runs", dest="frames", type=int, help=argparse.SUPPRESS)  # its name before --frames
    args = parser.parse_args()
    _harness.check_common(parser, args)
    width, height = parse_size(args.size)
    python = sys.executable
    settings = {"shading": args.shading, "build": args.build}
    with tempfile.TemporaryDirectory() as scratch, _harness.Records("startup", args, settings) as records:
        out = os.path.join(scratch, "x.png")
        base_env = dict(os.environ)
        values = {"usable_cores": usable_cores()}
        imports = [timed([python, "-c", "import raybench"], base_env) for _ in range(args.frames)]
        records.write(_harness.part("import", "cpu", imports, values=values))
        for _ in range(args.rounds):
            for device in args.device or ["cpu"]:
                render = [python, "-m", "raybench", "render", "--spheres", str(args.spheres), "--size", args.size,
                          "--device", device, "--shading", args.shading, "-o", out]  # fmt: skip
                if args.shading == "whitted":
                    render.insert(render.index("--spheres") + 2, "--materials")
                if args.build:
                    render += ["--build", args.build]
                cold = []
                for run in range(args.frames):
                    env = {**base_env, "RAYBENCH_CACHE_DIR": os.path.join(scratch, f"cold-{device}-{run}")}
                    cold.append(timed(render, env))
                warm_env = {**base_env, "RAYBENCH_CACHE_DIR": os.path.join(scratch, f"cold-{device}-0")}
                warm = [timed(render, warm_env) for _ in range(args.frames)]
                options = {"shading": args.shading, "build": args.build}
                for what, times in (("cold", cold), ("warm", warm)):
                    records.write(
                        _harness.part(
                            f"startup-{what}", device, times, spheres=args.spheres, width=width, height=height,
                            options=options, values=values,
                        )
                    )  # fmt: skip
    return 0


if __name__ == "__main__":
    sys.exit(main())
