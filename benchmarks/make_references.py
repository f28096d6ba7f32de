"""Regenerate raybench's reference results (src/raybench/references/references.jsonl.gz,
gzipped: the machine descriptions repeated on every line are most of it) from the
committed records under benchmarks/results/: the thesis's suites (tests 1-7, tuning,
constant-vs-runtime) and the secondary suite, on the machines below. `raybench bench` places
its headline against them, and the report judges the thesis's claims with them where this
machine lacks a device, saying so.

    python benchmarks/make_references.py          # rewrite the file
    python benchmarks/make_references.py --check  # exit 1 if it differs from what this makes

Each record is kept as measured, with its machine description, date and commit; two things
change: its run's label becomes the machine's name below (one machine, one label, whatever
its runs were called), and the run's argv is dropped (a command line of the lease machine).
To add a machine: commit its results under benchmarks/results/<machine>/ (files that
`raybench schema` accepts), add them to SOURCES, run this, and open a pull request.
"""

from __future__ import annotations

import argparse
import gzip
import json
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT / "src"))

from raybench.bench import results  # noqa: E402
from raybench.files import write_atomic  # noqa: E402

OUT = ROOT / "src" / "raybench" / "references" / "references.jsonl.gz"
SUITES = ("thesis", "test7", "tuning", "constant-vs-runtime", "secondary")
# machine name -> (file under benchmarks/results/, the suites taken from it); in this order
SOURCES = {
    "h200": [
        ("h200/kernels/thesis-20261129-d.jsonl", SUITES),
        ("h200/bvh-walk/tuning-bvh-20261129-d.jsonl", SUITES),
        ("h200/whitted/secondary-20261130-w4.jsonl", SUITES),
    ],
    "h100": [
        ("h100/fast-kernels-20261123/results-20261123-030428.jsonl", SUITES),
        ("h100/fast-kernels-20261123/results-20261123-030835.jsonl", SUITES),
        # the H100's only constant-vs-runtime run (its commit was not recorded)
        ("h100/results-20261122-230212.jsonl", ("constant-vs-runtime",)),
    ],
    "epyc-2c-cpu-only": [
        ("epyc-2c-cpu-only/kernels/results-20261122-231028.jsonl", SUITES),
        # the headline's points: the file above is the simple kernel's, from before the fast one
        # existed, and the headline counts the fast; the first of two back-to-back main jobs
        # (epyc-2c-cpu-only/headline/README.md says why that one and what the other read)
        ("epyc-2c-cpu-only/headline/main-job-20261203-112326.jsonl", SUITES),
        ("epyc-2c-cpu-only/whitted/secondary-20261130.jsonl", SUITES),
    ],
}


def make() -> bytes:
    """The reference file's bytes: every chosen record, one JSON line each, in SOURCES' order,
    gzipped with no time or name in its header, so the same records give the same bytes."""
    lines = []
    for machine, files in SOURCES.items():
        for name, suites in files:
            for record in results.read(ROOT / "benchmarks" / "results" / name):
                if record["suite"] not in suites:
                    continue
                run = {k: v for k, v in record["run"].items() if k != "argv"}
                run["label"] = machine
                lines.append(json.dumps({**record, "run": run}, separators=(",", ":"), sort_keys=False))
    text = ("\n".join(lines) + "\n").encode("utf-8")
    return gzip.compress(text, compresslevel=9, mtime=0)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--check", action="store_true", help="exit 1 if the committed file is not what this makes")
    args = parser.parse_args()
    data = make()
    if args.check:  # the records, not the gzip bytes: Python 3.13 writes another header, zlib may differ
        same = OUT.is_file() and gzip.decompress(OUT.read_bytes()) == gzip.decompress(data)
        print(f"{OUT}: {'up to date' if same else 'differs; run benchmarks/make_references.py'}")
        return 0 if same else 1
    write_atomic(OUT, data)
    print(f"wrote {OUT}: {len(gzip.decompress(data).splitlines())} records, {len(data) / 1024:.0f} KiB")
    return 0


if __name__ == "__main__":
    sys.exit(main())
