"""Rewrite committed benchmark records into the results schema (raybench.bench.results), so
that `raybench report` reads them. Run once, on the files named; a file already in the schema
is left as it is. Only records whose samples the schema can hold are converted: the frame
times' median, p5 and p95 come from the record's own list of runs or frames, never made up.

    python benchmarks/archive/convert_results.py FILE.jsonl... --machine h200

Each converted record keeps the original, whole, under "source" (fields the schema does not
name pass its checks), and names its run after the file. What is converted:

- benchmarks/multi_gpu.py's records (jobs "frame" and "orbit", with "seconds" a run) become
  suite "multi-gpu" points, as `raybench bench --suite multi-gpu` writes them: frame_ms is a
  run's wall time over its frames, per run; options carry workers, job ("orbit" is the suite's
  "sequence"), frames, accel and threads.
- benchmarks/cpu_tree_width.py's records (one per layout and size, both trees' frames) become
  two suite "scaling" points each, the binary and the 4-wide tree (options.tree_width 2 or 4),
  in two runs labelled -binary and -wide, which the report shows apart.
- the Whitted wide-tree probe's records (binary_all_ms and wide_all_ms, one per layout and
  size) become two suite "secondary" points each, Whitted shading, options.tree_width 2 or 4,
  in two runs as above. The probe timed the kernel alone, so frame_ms is the kernel's time.

Everything else refused by `raybench report` has no per-run samples or measures something
that is not a frame (builds, start-up, launches, readback parts, Mitsuba's side); those files
are kept under benchmarks/results/archive/ (its README says why).
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from raybench.bench import results
from raybench.bench.stats import summarize

# What is known of each machine folder's machine, for the run's "machine" (every field is optional
# in the schema; the records themselves did not carry it).
MACHINES = {
    "h200": {
        "cpu": {"model": "Intel Xeon (the H200 machine's host)", "arch": "x86_64"},
        "gpus": [{"name": "NVIDIA H200"}],
    },
    "epyc-2c-cpu-only": {"cpu": {"model": "AMD EPYC", "arch": "x86_64", "logical_cpus": 2, "simd": "AVX2"}},
    "epyc-zen4-2c": {"cpu": {"model": "AMD EPYC (Zen 4)", "arch": "x86_64", "logical_cpus": 2, "simd": "AVX-512"}},
}


def run_of(
    path: Path, machine: str, commit: str | None, command: str, extra: dict | None = None, side: str = ""
) -> dict:
    """The run of a converted file (a side's, where one record held two variants: the report
    tells runs apart by their labels)."""
    name = path.stem
    label = f"{machine}-{name}{side}"[:64]
    m = dict(MACHINES[machine])
    if extra:
        m.update(extra)
    return {
        "id": name + side,
        "date": next((part for part in name.split("-") if part.startswith("2026") and len(part) == 8), None),
        "git_commit": commit,
        "label": label,
        "argv": [command],
        "settings": {"converted_by": "benchmarks/convert_results.py", "converted_from": path.name},
        "machine": m,
    }


def multi_gpu(record: dict, path: Path, machine: str) -> list[dict]:
    frames = record["frames"]
    samples = [s * 1e3 / frames for s in record["seconds"]]
    frame_ms = summarize(samples)
    job = "sequence" if record["job"] == "orbit" else "frame"
    options = {"workers": record["workers"], "job": job, **record.get("options", {})}
    if job == "sequence":
        options["frames"] = frames
    for key in ("rows", "tasks", "shared"):
        if key in record:
            options[key] = record[key]
    gpus = record["workers"] if record["device"] == "cuda" else None
    extra = {"gpus": [{"name": "NVIDIA H200"}] * max(gpus, 1)} if gpus else None
    run = run_of(path, machine, record.get("git_commit"), "benchmarks/multi_gpu.py", extra)
    return [
        {
            "suite": "multi-gpu",
            "test": None,
            "device": record["device"],
            "width": record["width"],
            "height": record["height"],
            "spheres": record["spheres"],
            "options": options,
            "frames": frames * len(samples),
            "frame_ms": frame_ms,
            "kernel_ms": None,
            "first_frame_s": record.get("first_s"),
            "compile_s": None,
            "build_s": None,
            "rays_per_s": record["width"] * record["height"] / (frame_ms["median"] / 1e3),
            "tests_per_s": None,
            "frames_per_s": 1e3 / frame_ms["median"],
            "run": run,
            "source": record,
        }
    ]


def tree_width(record: dict, path: Path, machine: str) -> list[dict]:
    out = []
    for width, side in ((2, "binary"), (4, "wide")):
        run = run_of(path, machine, record.get("raybench_commit"), "benchmarks/cpu_tree_width.py", side=f"-{side}")
        if record.get("processor"):
            run["machine"] = {"cpu": record["processor"]}
        frame_ms = summarize(record[f"{side}_frames_ms"])
        out.append(
            {
                "suite": "scaling",
                "test": None,
                "device": "cpu",
                "width": record["width"],
                "height": record["height"],
                "spheres": record["spheres"],
                "options": {
                    "threads": record["threads"],
                    "accel": "bvh",
                    "layout": record["layout"],
                    "tree_width": width,
                },
                "frames": len(record[f"{side}_frames_ms"]),
                "frame_ms": frame_ms,
                "kernel_ms": None,
                "build_s": record.get(f"{side}_build_s"),
                "rays_per_s": record["width"] * record["height"] / (frame_ms["median"] / 1e3),
                "tests_per_s": None,
                "run": run,
                "source": record,
            }
        )
    return out


def whitted_wide(record: dict, path: Path, machine: str) -> list[dict]:
    out = []
    for width, side in ((2, "binary"), (4, "wide")):
        run = run_of(
            path,
            machine,
            record.get("git_commit"),
            "the Whitted wide-tree probe (branch wide-whitted)",
            side=f"-{side}",
        )
        if record.get("machine"):
            run["machine"] = record["machine"]
        kernel_ms = summarize(record[f"{side}_all_ms"])
        out.append(
            {
                "suite": "secondary",
                "test": None,
                "device": record["device"],
                "width": record["width"],
                "height": record["height"],
                "spheres": record["spheres"],
                "options": {
                    "accel": "bvh",
                    "shading": "whitted",
                    "depth": record["depth"],
                    "shadow_samples": record["shadow_samples"],
                    "layout": record["layout"],
                    "tree_width": width,
                },
                "frames": len(record[f"{side}_all_ms"]),
                # the probe timed the kernel alone (CUDA events); the frame's time was not kept
                "frame_ms": kernel_ms,
                "kernel_ms": kernel_ms,
                "build_s": None,
                "rays_per_s": record["rays"] / (kernel_ms["median"] / 1e3),
                "tests_per_s": None,
                "rays_per_frame": record["rays"],
                "kernel_rays_per_s": record["rays"] / (kernel_ms["median"] / 1e3),
                "run": run,
                "source": record,
            }
        )
    return out


def converter(record: dict):
    if "seconds" in record and record.get("job") in ("frame", "orbit"):
        return multi_gpu
    if record.get("what") == "cpu_tree_width":
        return tree_width
    if "binary_all_ms" in record and "wide_all_ms" in record:
        return whitted_wide
    return None


def convert(path: Path, machine: str) -> bool:
    """Rewrite path in the schema; False (and nothing written) where a record cannot be."""
    lines = [line for line in path.read_text().splitlines() if line.strip()]
    records = [json.loads(line) for line in lines]
    if all(r.get("format") == results.FORMAT for r in records):
        return True
    out = []
    for record in records:
        convert_one = converter(record)
        if convert_one is None:
            return False
        out.extend(convert_one(record, path, machine))
    text = "".join(
        json.dumps({"format": results.FORMAT, "version": results.VERSION, **r}, separators=(",", ":")) + "\n"
        for r in out
    )
    path.write_text(text)
    results.read(path)  # the schema's own check: raises, naming the field, if a record does not fit
    return True


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("files", nargs="+", type=Path)
    parser.add_argument("--machine", required=True, choices=sorted(MACHINES))
    args = parser.parse_args(argv)
    for path in args.files:
        print(f"{path}: {'in the schema' if convert(path, args.machine) else 'not convertible'}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
