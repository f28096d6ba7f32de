"""Warm starts of several versions and render options side by side: each
variant's cache filled by one cold run, then its warm runs interleaved with
the others', round by round, so that a slow spell of the machine falls on
every variant alike. One line of JSON a run, then each variant's median.

    python benchmarks/startup_paired.py --version base=base-a48cd5b --version new=src \\
        --variant "host=--device cuda --build host" --variant "gpu=--device cuda --build gpu"

A version is NAME=DIR, DIR holding that version's `raybench` package (put
first on PYTHONPATH); a variant is NAME=ARGS, the arguments added to
`raybench render --spheres 1000 --size 1680x1050` (--spheres and --size may
be given again). --profile also writes a cProfile listing of one warm run of
each variant of the last version.
"""

import argparse
import io
import json
import os
import pstats
import shlex
import statistics
import subprocess
import sys
import tempfile
import time


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--version", action="append", required=True, help="NAME=DIR")
    parser.add_argument("--variant", action="append", required=True, help="NAME=ARGS")
    parser.add_argument("--rounds", type=int, default=5)
    parser.add_argument("--profile", metavar="DIR", help="write cProfile listings of warm runs here")
    args = parser.parse_args()
    versions = dict(v.split("=", 1) for v in args.version)
    variants = {name: shlex.split(rest) for name, rest in (v.split("=", 1) for v in args.variant)}
    path = os.environ.get("PYTHONPATH", "")
    with tempfile.TemporaryDirectory() as scratch:
        out = os.path.join(scratch, "x.png")

        def run(version, variant, profile=None):
            env = {
                **os.environ,
                "RAYBENCH_CACHE_DIR": os.path.join(scratch, f"{version}-{variant}"),
                "PYTHONPATH": os.pathsep.join(p for p in (os.path.abspath(versions[version]), path) if p),
            }
            command = [sys.executable, *(["-m", "cProfile", "-o", profile] if profile else []), "-m", "raybench"]
            command += ["render", "--spheres", "1000", "--size", "1680x1050", *variants[variant], "-o", out]
            start = time.perf_counter()
            ran = subprocess.run(command, env=env, capture_output=True, text=True, check=True)
            return time.perf_counter() - start, ran.stdout.strip()

        for version in versions:
            for variant in variants:
                took, said = run(version, variant)
                print(json.dumps({"what": "cold", "version": version, "variant": variant, "s": round(took, 3),
                                  "said": said}), flush=True)  # fmt: skip
        warm = {(v, w): [] for v in versions for w in variants}
        for round_ in range(args.rounds):
            for key in warm:
                took, _ = run(*key)
                warm[key].append(took)
                print(json.dumps({"what": "warm", "round": round_, "version": key[0], "variant": key[1],
                                  "s": round(took, 3)}), flush=True)  # fmt: skip
        for (version, variant), times in warm.items():
            print(json.dumps({"what": "warm median", "version": version, "variant": variant,
                              "median_s": round(statistics.median(times), 3)}), flush=True)  # fmt: skip
        if args.profile:
            os.makedirs(args.profile, exist_ok=True)
            last = list(versions)[-1]
            for variant in variants:
                listing = os.path.join(scratch, f"{variant}.prof")
                run(last, variant, profile=listing)
                text = io.StringIO()
                pstats.Stats(listing, stream=text).sort_stats("cumulative").print_stats(60)
                with open(os.path.join(args.profile, f"profile-warm-{last}-{variant}.txt"), "w") as f:
                    f.write(text.getvalue())
    return 0


if __name__ == "__main__":
    sys.exit(main())
