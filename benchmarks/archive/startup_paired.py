"""Warm starts of several versions and render options side by side: each
variant's cache filled by one cold run, then its warm runs interleaved with
the others', round by round, so that a slow spell of the machine falls on
every variant alike. One record of the results schema's "parts" suite a
version and variant for its cold run (quantity "startup-cold") and one for
its warm runs ("startup-warm"), options naming the version and the variant.

    PYTHONPATH=benchmarks python benchmarks/archive/startup_paired.py --version base=base-a48cd5b --version new=src \\
        --variant "host=--device cuda --build host" --variant "gpu=--device cuda --build gpu"

A version is NAME=DIR, DIR holding that version's `raybench` package (put
first on PYTHONPATH); a variant is NAME=ARGS, the arguments added to
`raybench render --spheres 1000 --size 1680x1050` (--spheres and --size may
be given again). --profile also writes a cProfile listing of one warm run of
each variant of the last version.
"""

import argparse
import io
import os
import pstats
import shlex
import subprocess
import sys
import tempfile

import _harness


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--version", action="append", required=True, help="NAME=DIR")
    parser.add_argument("--variant", action="append", required=True, help="NAME=ARGS")
    parser.add_argument("--profile", metavar="DIR", help="write cProfile listings of warm runs here")
    _harness.add_common(parser, frames=1, rounds=5)
    args = parser.parse_args()
    _harness.check_common(parser, args)
    versions = dict(v.split("=", 1) for v in args.version)
    variants = {name: shlex.split(rest) for name, rest in (v.split("=", 1) for v in args.variant)}
    path = os.environ.get("PYTHONPATH", "")
    settings = {"versions": [f"{k}={v}" for k, v in versions.items()], "variants": args.variant}
    with tempfile.TemporaryDirectory() as scratch, _harness.Records("startup_paired", args, settings) as records:
        out = os.path.join(scratch, "x.png")

        def run(version, variant, profile=None):
            env = {
                **os.environ,
                "RAYBENCH_CACHE_DIR": os.path.join(scratch, f"{version}-{variant}"),
                "PYTHONPATH": os.pathsep.join(p for p in (os.path.abspath(versions[version]), path) if p),
            }
            command = [sys.executable, *(["-m", "cProfile", "-o", profile] if profile else []), "-m", "raybench"]
            command += ["render", "--spheres", "1000", "--size", "1680x1050", *variants[variant], "-o", out]
            return _harness.timings(lambda: subprocess.run(command, env=env, capture_output=True, check=True), 1)[0]

        def write(what, version, variant, times):
            given = variants[variant]
            device = given[given.index("--device") + 1] if "--device" in given[:-1] else "cpu"
            options = {"version": version, "variant": variant}
            records.write(_harness.part(f"startup-{what}", device, times, options=options))

        for version in versions:
            for variant in variants:
                write("cold", version, variant, [run(version, variant)])
        keys = [(v, w) for v in versions for w in variants]
        warm = _harness.paired({key: (lambda key=key: [run(*key) for _ in range(args.frames)]) for key in keys},
                               args.rounds)  # fmt: skip
        for (version, variant), times in warm.items():
            write("warm", version, variant, times)
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
