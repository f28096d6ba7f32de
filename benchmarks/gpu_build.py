"""The BVH built on the GPU (backends.cuda.build) against the host's binned
SAH build (raybench.bvh), on random_spheres(n, seed=0), one JSON record per
sphere count (printed as it is measured, and all of them written to --json
with the machine and the commit):

- the GPU build's time, warm: CUDA events around all its kernels (median of
  --repeats), each step's share (events between the steps), and the wall
  time from the first launch to the depth read back (the tree ready to walk,
  Python's launch overhead included);
- the refit's time (the boxes from moved spheres, the tree kept), by events;
- the host build's time (compiled code, every core, as raybench reports it)
  and its upload;
- the SAH cost of both trees (raybench.bvh.cost), and their depths and rows;
- the walk's kernel time on each tree (1680x1050, the default camera), both
  walks (a ray at a time, packets), median of --frames, and the share of
  pixels whose hit differs between the two trees (0 on a GPU, up to the
  compiler's fused multiply-adds; the tests hold it to the brute force);
- moving spheres (raybench.animate.Orbits, seed 0, --anim-frames frames
  --anim-dt seconds apart): per frame, the tree's update (Tracer.update:
  refit or build) and the walk, under four policies: the default
  (cuda_build.REFIT_LIMIT), refit only, rebuild every frame, and the host's
  build; with the refitted tree's SAH cost over its fresh cost, the series
  from which REFIT_LIMIT is chosen (rebuild once the walk's loss on the
  refitted tree exceeds the build's cost over the refit's);
- the GPU tree's largest leaf (cuda_build.Builder's leaf_size, in the
  default quality) swept over --leaf-size: its SAH cost and both walks'
  times, to choose it.

The GPU build's figures (time, steps, SAH cost, walks) are given for each
quality of tree in --quality (default all of cuda_build.QUALITIES: "sah",
the LBVH with its leaves cut where the SAH says; "treelet", the same with
each row's treelet rebuilt where the SAH says and the spheres reordered;
"lbvh", the LBVH with fixed leaves of LEAF_SIZE), under "variants",
side by side (a quality that fails is recorded with its error); the record's
top-level gpu_* and walk_* fields are the default quality's
(cuda_build.QUALITY), which the dynamic series use.

    python benchmarks/gpu_build.py --json out.json [--spheres 1000 --spheres 100000] [--repeats 51]
        [--quality sah --quality treelet] [--anim-frames 40 --anim-dt 0.1]

Issue 16's targets (H200): a build of 1,000,000 spheres in at most 5 ms,
100,000 in 1 ms, the walk on the GPU's tree at most 10% slower than on the
host's.
"""

import argparse
import json
import statistics
import sys
import time

import numpy as np
from numba import cuda

import raybench
from raybench import Camera, backends, bvh, files, machine
from raybench.backends.cuda import build as cuda_build
from raybench.bvh import cost as tree_cost

STEPS = ("codes", "sort", "hierarchy", "bounds")


def events_ms(marks) -> list[float]:
    """The ms between consecutive recorded events (after the last one is done)."""
    marks[-1].synchronize()
    return [a.elapsed_time(b) for a, b in zip(marks, marks[1:])]


def gpu_build(spheres: np.ndarray, repeats: int, quality: str) -> dict:
    n = spheres.shape[1]
    d_spheres = cuda.to_device(spheres)
    builder = cuda_build.Builder(n, quality=quality)  # its default leaf size
    for _ in range(3):  # compiled (or loaded from the cache), warm
        builder.launch_build(d_spheres)
        builder.read_depth()
    whole, steps, wall, refit = [], {s: [] for s in STEPS}, [], []
    for _ in range(repeats):
        marks = [cuda.event() for _ in range(len(STEPS) + 1)]
        marks[0].record()
        builder.launch_codes(d_spheres)
        marks[1].record()
        builder.launch_sort()
        marks[2].record()
        builder.launch_hierarchy()
        marks[3].record()
        builder.launch_bounds(d_spheres)
        marks[4].record()
        parts = events_ms(marks)
        whole.append(sum(parts))
        for name, ms in zip(STEPS, parts):
            steps[name].append(ms)
        start = time.perf_counter()
        builder.launch_build(d_spheres)
        depth = builder.read_depth()
        wall.append((time.perf_counter() - start) * 1e3)
        marks = [cuda.event(), cuda.event()]
        marks[0].record()
        builder.launch_refit(d_spheres)
        marks[1].record()
        refit.append(events_ms(marks)[0])
    builder.launch_build(d_spheres)  # the refits above kept the tree; its boxes fresh again
    tree = builder.tree(builder.read_depth(), 0.0).to_host()
    return {
        "gpu_build_ms": round(statistics.median(whole), 4),
        "gpu_build_p5_p95_ms": [round(float(v), 4) for v in np.percentile(whole, [5, 95])],
        "gpu_build_steps_ms": {k: round(statistics.median(v), 4) for k, v in steps.items()},
        "gpu_build_wall_ms": round(statistics.median(wall), 4),
        "gpu_refit_ms": round(statistics.median(refit), 4),
        "gpu_depth": depth,
        "gpu_rows": tree.node_count,
        "gpu_rows_walked": builder.read_rows(),
        "gpu_sah": round(tree_cost.sah_cost(tree.nodes), 3),
    }


def host_build(spheres: np.ndarray, repeats: int) -> dict:
    bvh.compile_builder()
    times = [bvh.build(spheres, _timed=False).build_s * 1e3 for _ in range(max(3, repeats // 5))]
    tree = bvh.build(spheres, _timed=False)
    start = time.perf_counter()
    cuda_build.upload(tree)
    cuda.synchronize()
    upload_ms = (time.perf_counter() - start) * 1e3
    return {
        "host_build_ms": round(statistics.median(times), 3),
        "host_upload_ms": round(upload_ms, 3),
        "host_depth": tree.depth,
        "host_rows": tree.node_count,
        "host_sah": round(tree_cost.sah_cost(tree.nodes), 3),
    }


def use_tree(tracer, tree) -> None:
    """The tracer's tree replaced by tree (a cuda_build.GpuTree)."""
    tracer.bvh = tree
    tracer.d_nodes, tracer.d_links, tracer.d_ordered, tracer.d_order = tree.nodes, tree.links, tree.ordered, tree.order


def walks(spheres: np.ndarray, width: int, height: int, frames: int, qualities) -> dict:
    """Both walks' kernel times on the host's tree and on the GPU's tree of
    each quality, and the share of hits differing from the host tree's."""
    basis = Camera().basis(width, height)
    d_spheres = cuda.to_device(spheres)
    out, hits = {}, {}
    for walk in ("ray", "packet"):
        with backends.tracer("cuda", spheres, width, height, build="host", walk=walk) as tracer:
            tracer.trace(basis)
            times = [tracer.timed_trace(basis) for _ in range(frames)]  # None under the simulator
            out[f"walk_host_{walk}_ms"] = round(statistics.median(t or np.nan for t in times), 4)
            hits["host"] = tracer.hits.copy()
        with backends.tracer("cuda", spheres, width, height, build="gpu", walk=walk) as tracer:
            for quality in qualities:
                entry = out.setdefault(quality, {})
                try:
                    builder = cuda_build.Builder(spheres.shape[1], quality=quality)
                    builder.launch_build(d_spheres)
                    use_tree(tracer, builder.tree(builder.read_depth(), 0.0))
                    tracer.trace(basis)
                    times = [tracer.timed_trace(basis) for _ in range(frames)]
                except Exception as e:  # noqa: BLE001 (one quality failing leaves the others measured)
                    entry["error"] = repr(e)
                    continue
                entry[f"walk_gpu_{walk}_ms"] = round(statistics.median(t or np.nan for t in times), 4)
                entry[f"walk_gpu_over_host_{walk}"] = round(
                    entry[f"walk_gpu_{walk}_ms"] / out[f"walk_host_{walk}_ms"], 4
                )
                entry["hits_differ"] = max(entry.get("hits_differ", 0.0), float((hits["host"] != tracer.hits).mean()))
    return out


POLICIES = {"default": ("gpu", None), "refit-only": ("gpu", np.inf), "rebuild": ("gpu", 0.0), "host": ("host", None)}


def gpu_cost(tracer) -> float | None:
    """The SAH cost of the tree the Tracer walks (bvh.cost.sah_cost, on the host), where the GPU
    built it; else None."""
    tree = tracer.bvh
    if tree is None or getattr(tree, "built_on", None) != "gpu":
        return None
    return tree_cost.sah_cost(tree.to_host().nodes)


def dynamic(spheres: np.ndarray, width: int, height: int, frames: int, dt: float) -> dict:
    """Per policy: per frame, the update's wall ms and kind, the walk's kernel
    ms, the whole frame's wall ms (update, walk, image and hits to the host)
    and, on the GPU's trees, the SAH cost over the fresh tree's."""
    from raybench import animate

    basis = Camera().basis(width, height)
    orbits = animate.Orbits(spheres, 0)
    moved = [orbits.at(k * dt) for k in range(1, frames + 1)]
    out = {}
    for name, (build, limit) in POLICIES.items():
        saved = cuda_build.REFIT_LIMIT
        if limit is not None:
            cuda_build.REFIT_LIMIT = limit
        try:
            with backends.tracer("cuda", spheres, width, height, build=build) as tracer:
                tracer.trace(basis)
                fresh = gpu_cost(tracer)
                series = {"update_ms": [], "kind": [], "walk_ms": [], "frame_ms": [], "cost_ratio": []}
                for frame in moved:
                    start = time.perf_counter()
                    kind = tracer.update(frame)
                    update_ms = (time.perf_counter() - start) * 1e3
                    walk_ms = tracer.timed_trace(basis)
                    series["frame_ms"].append(round((time.perf_counter() - start) * 1e3, 4))
                    series["update_ms"].append(round(update_ms, 4))
                    series["kind"].append(kind)
                    series["walk_ms"].append(round(walk_ms or np.nan, 4))
                    cost = gpu_cost(tracer)
                    if kind == "build":  # a fresh tree, as the Tracer's refit limit counts from
                        fresh = cost
                    if cost is not None and fresh:
                        series["cost_ratio"].append(round(cost / fresh, 4))
                series["median_frame_ms"] = round(statistics.median(series["frame_ms"]), 4)
                series["fps"] = round(1e3 / series["median_frame_ms"], 2)
                out[name] = series
        finally:
            cuda_build.REFIT_LIMIT = saved
    return out


def leaf_sizes(spheres: np.ndarray, width: int, height: int, frames: int, sizes) -> dict:
    """Per largest leaf: the GPU tree's SAH cost (default quality) and both
    walks' kernel times (the tracer's tree replaced by one built with it)."""
    basis = Camera().basis(width, height)
    d_spheres = cuda.to_device(spheres)
    out = {}
    for walk in ("ray", "packet"):
        with backends.tracer("cuda", spheres, width, height, build="gpu", walk=walk) as tracer:
            for size in sizes:
                builder = cuda_build.Builder(spheres.shape[1], size)
                builder.launch_build(d_spheres)
                tree = builder.tree(builder.read_depth(), 0.0)
                use_tree(tracer, tree)
                tracer.trace(basis)
                times = [tracer.timed_trace(basis) for _ in range(frames)]
                entry = out.setdefault(str(size), {"sah": round(tree_cost.sah_cost(tree.to_host().nodes), 3)})
                entry[f"walk_{walk}_ms"] = round(statistics.median(t or np.nan for t in times), 4)
    return out


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--json", required=True, help="file for all the records, with the machine and commit")
    parser.add_argument("--spheres", action="append", type=int, help="default: 1000, 100000, 1000000")
    parser.add_argument("--size", default="1680x1050")
    parser.add_argument("--repeats", type=int, default=51, help="timed GPU builds (and refits) per count")
    parser.add_argument("--frames", type=int, default=15, help="timed frames per walk")
    parser.add_argument("--leaf-size", type=int, action="append", help="largest leaves to sweep (default 1, 2, 4, 8)")
    parser.add_argument(
        "--quality", action="append", choices=cuda_build.QUALITIES, help="GPU trees to measure (default all)"
    )
    parser.add_argument(
        "--treelet-passes", type=int, default=cuda_build.TREELET_PASSES, help="bottom-up passes of treelets"
    )
    parser.add_argument("--anim-frames", type=int, default=40, help="frames of moving spheres per policy")
    parser.add_argument("--anim-dt", type=float, default=0.1, help="seconds of the animation between frames")
    args = parser.parse_args()
    cuda_build.TREELET_PASSES = args.treelet_passes
    width, height = (int(v) for v in args.size.split("x"))
    records = []
    for n in args.spheres or [1000, 100_000, 1_000_000]:
        spheres = raybench.random_spheres(n, seed=0).spheres
        row = {"spheres": n, "width": width, "height": height, "treelet_passes": cuda_build.TREELET_PASSES}
        row.update(host_build(spheres, args.repeats))
        qualities = args.quality or list(cuda_build.QUALITIES)
        walked = walks(spheres, width, height, args.frames, qualities)
        row.update({k: v for k, v in walked.items() if k.startswith("walk_host_")})
        variants = {}
        for quality in qualities:
            if "error" in walked[quality]:
                variants[quality] = walked[quality]
                print(f"{n:>9,} spheres, {quality:>7}: {walked[quality]['error']}", file=sys.stderr, flush=True)
                continue
            entry = gpu_build(spheres, args.repeats, quality)
            entry["sah_gpu_over_host"] = round(entry["gpu_sah"] / row["host_sah"], 4)
            entry.update(walked[quality])
            variants[quality] = entry
            print(
                f"{n:>9,} spheres, {quality:>7}: build {entry['gpu_build_ms']:.3f} ms, SAH / host "
                f"{entry['sah_gpu_over_host']:.3f}, walk / host: ray {entry['walk_gpu_over_host_ray']:.3f}, "
                f"packet {entry['walk_gpu_over_host_packet']:.3f}",
                file=sys.stderr,
                flush=True,
            )
        row["variants"] = variants
        row["quality"] = cuda_build.QUALITY
        row.update(variants.get(cuda_build.QUALITY, {}))  # the default's, as the fields were before
        row["leaf_size"] = cuda_build.LEAF_SIZE
        row["leaf_sizes"] = leaf_sizes(spheres, width, height, args.frames, args.leaf_size or [1, 2, 4, 8])
        if args.anim_frames > 0:
            row["dynamic"] = dynamic(spheres, width, height, args.anim_frames, args.anim_dt)
        print(json.dumps(row), flush=True)
        records.append(row)
    out = {
        "benchmark": "gpu_build",
        "argv": sys.argv,
        "git_commit": machine.git_commit(),
        "machine": machine.describe(),
        "records": records,
    }
    files.write_atomic(args.json, json.dumps(out, indent=1).encode())
    return 0


if __name__ == "__main__":
    sys.exit(main())
