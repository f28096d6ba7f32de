"""The BVH built on the GPU (backends.cuda.build) against the host's binned
SAH build (raybench.bvh), on random_spheres(n, seed=0), as records of the
results schema: the builds and refits in its "parts" suite (quantity
"bvh-build" and "bvh-upload" for the host's; "gpu-build", "gpu-build-wall",
"gpu-build-" and a step, "gpu-refit", options naming the quality, the trees'
SAH costs, depths and rows as figures), the walks on each tree in its
"scaling" suite (options build and quality, the walk that ran), the leaf-size
sweep in "parts" (quantity "gpu-tree-leaf-walk", the walk's kernel time), the
moving spheres in its "dynamic" suite (option policy):

- the GPU build's time, warm: CUDA events around all its kernels (--repeats
  builds), each step's share (events between the steps), and the wall
  time from the first launch to the depth read back (the tree ready to walk,
  Python's launch overhead included);
- the refit's time (the boxes from moved spheres, the tree kept), by events;
- the host build's time (compiled code, every core, as raybench reports it)
  and its upload;
- the SAH cost of both trees (raybench.bvh.cost), and their depths and rows;
- the walk's kernel time on each tree (1680x1050, the default camera), both
  walks (a ray at a time, packets), --frames frames, and the share of
  pixels whose hit differs between the two trees (0 on a GPU, up to the
  compiler's fused multiply-adds; the tests hold it to the brute force);
- moving spheres (raybench.animate.Orbits, seed 0, --anim-frames frames
  --anim-dt seconds apart): per frame, the tree's update (Tracer.update:
  refit or build) and the walk, under four policies: the default
  (lbvh.REFIT_LIMIT), refit only, rebuild every frame, and the host's
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

    python benchmarks/gpu_build.py --out out.jsonl [--spheres 1000 --spheres 100000] [--repeats 51]
        [--quality sah --quality treelet] [--anim-frames 40 --anim-dt 0.1]

Issue 16's targets (H200): a build of 1,000,000 spheres in at most 5 ms,
100,000 in 1 ms, the walk on the GPU's tree at most 10% slower than on the
host's.
"""

import argparse
import sys
import time

import _harness
import numpy as np
from numba import cuda

import raybench
from raybench import Camera, backends, bvh
from raybench.backends.cuda import build as cuda_build
from raybench.bench.stats import summarize
from raybench.bvh import cost as tree_cost
from raybench.bvh import lbvh

STEPS = ("codes", "sort", "hierarchy", "bounds")


def events_ms(marks) -> list[float]:
    """The ms between consecutive recorded events (after the last one is done)."""
    marks[-1].synchronize()
    return [a.elapsed_time(b) for a, b in zip(marks, marks[1:])]


def gpu_build(
    spheres: np.ndarray, repeats: int, quality: str, passes: int, primitive: str = "sphere"
) -> tuple[dict, dict]:
    """({quantity: ms of each build}, the tree's figures); spheres: the scene's
    buffer of that kind of primitive (benchmarks/mesh_build.py times triangles)."""
    from raybench.backends.cuda import kinds

    n = spheres.shape[1]
    d_spheres = cuda.to_device(spheres)
    kind = None if primitive == "sphere" else kinds.programs(primitive).build
    builder = cuda_build.Builder(n, quality=quality, treelet_passes=passes, kind=kind)  # its default leaf size
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
    timings = {"gpu-build": whole, "gpu-build-wall": wall, "gpu-refit": refit,
               **{f"gpu-build-{s}": v for s, v in steps.items()}}  # fmt: skip
    figures = {"depth": depth, "rows": tree.node_count, "rows_walked": builder.read_rows(),
               "sah": round(tree_cost.sah_cost(tree.nodes), 3)}  # fmt: skip
    # the simulator's events time nothing: no record of them
    return {name: ms for name, ms in timings.items() if min(ms) > 0}, figures


def host_build(spheres: np.ndarray, repeats: int) -> list[dict]:
    """The host's builds and the tree's upload, records of the parts suite."""
    bvh.compile_builder()
    times = [bvh.build(spheres).build_s * 1e3 for _ in range(max(3, repeats // 5))]
    tree = bvh.build(spheres)

    def upload():
        cuda_build.upload(tree)
        cuda.synchronize()

    n = spheres.shape[1]
    values = {"depth": tree.depth, "rows": tree.node_count, "sah": round(tree_cost.sah_cost(tree.nodes), 3)}
    return [
        _harness.part("bvh-build", "cpu", times, spheres=n, values=values),
        _harness.part("bvh-upload", "cuda", _harness.timings(upload, 1), spheres=n),
    ]


def use_tree(tracer, tree) -> None:
    """The tracer's tree replaced by tree (a cuda_build.GpuTree)."""
    tracer.bvh = tree
    tracer.d_nodes, tracer.d_links, tracer.d_ordered, tracer.d_order = tree.nodes, tree.links, tree.ordered, tree.order


def timed_frames(tracer, basis, frames: int) -> tuple[list[float], list[float] | None]:
    """Whole frames' ms, and the kernel's (None under the simulator)."""
    tracer.trace(basis)
    kernel = []
    wall = _harness.timings(lambda: kernel.append(tracer.timed_trace(basis)), frames)
    return wall, (kernel if kernel[0] is not None else None)


def walks(spheres: np.ndarray, width: int, height: int, frames: int, qualities, passes: int) -> list[dict]:
    """Both walks on the host's tree and on the GPU's tree of each quality: points of the
    scaling suite, the GPU trees' with the share of hits differing from the host tree's (a
    quality that fails is left out, its error on stderr)."""
    basis = Camera().basis(width, height)
    d_spheres = cuda.to_device(spheres)
    n = spheres.shape[1]
    out = []
    for walk in ("ray", "packet"):
        with backends.tracer("cuda", spheres, width, height, build="host", walk=walk) as tracer:
            options = {"accel": "bvh", "build": "host", "walk": walk}
            record = _harness.point("scaling", "cuda", width, height, n, options, *timed_frames(tracer, basis, frames),
                                    build_s=tracer.build_s)  # fmt: skip
            record["walk"] = walk
            out.append(record)
            host_hits = tracer.hits.copy()
        with backends.tracer("cuda", spheres, width, height, build="gpu", walk=walk) as tracer:
            for quality in qualities:
                try:
                    builder = cuda_build.Builder(n, quality=quality, treelet_passes=passes)
                    builder.launch_build(d_spheres)
                    use_tree(tracer, builder.tree(builder.read_depth(), 0.0))
                    timed = timed_frames(tracer, basis, frames)
                except Exception as e:  # noqa: BLE001 (one quality failing leaves the others measured)
                    print(f"{n:>9,} spheres, {quality}, {walk} walk: {e!r}", file=sys.stderr, flush=True)
                    continue
                options = {"accel": "bvh", "build": "gpu", "quality": quality, "walk": walk}
                record = _harness.point("scaling", "cuda", width, height, n, options, *timed)
                record["walk"] = walk
                record["hits_differ"] = float((host_hits != tracer.hits).mean())
                out.append(record)
    return out


POLICIES = {"default": ("gpu", None), "refit-only": ("gpu", np.inf), "rebuild": ("gpu", 0.0), "host": ("host", None)}


def gpu_cost(tracer) -> float | None:
    """The SAH cost of the tree the Tracer walks (bvh.cost.sah_cost, on the host), where the GPU
    built it; else None."""
    tree = tracer.bvh
    if tree is None or getattr(tree, "built_on", None) != "gpu":
        return None
    return tree_cost.sah_cost(tree.to_host().nodes)


def dynamic(spheres: np.ndarray, width: int, height: int, frames: int, dt: float) -> list[dict]:
    """Per policy, a point of the dynamic suite: per frame, the update's wall ms and kind, the
    walk's kernel ms, the whole frame's wall ms (update, walk, image and hits to the host) and,
    on the GPU's trees, the SAH cost over the fresh tree's (cost_ratio)."""
    from raybench import animate

    basis = Camera().basis(width, height)
    orbits = animate.Orbits(spheres, 0)
    moved = [orbits.at(k * dt) for k in range(1, frames + 1)]
    out = []
    for name, (build, limit) in POLICIES.items():
        policy = {} if limit is None else {"refit_limit": limit}
        with backends.tracer("cuda", spheres, width, height, build=build, **policy) as tracer:
            tracer.trace(basis)
            fresh = gpu_cost(tracer)
            update_ms, kinds, walk_ms, frame_ms, cost_ratio = [], [], [], [], []
            for frame in moved:
                start = time.perf_counter()
                kind = tracer.update(frame)
                update_ms.append((time.perf_counter() - start) * 1e3)
                walk_ms.append(tracer.timed_trace(basis))
                frame_ms.append((time.perf_counter() - start) * 1e3)
                kinds.append(kind)
                cost = gpu_cost(tracer)
                if kind == "build":  # a fresh tree, as the Tracer's refit limit counts from
                    fresh = cost
                if cost is not None and fresh:
                    cost_ratio.append(round(cost / fresh, 4))
        options = {"accel": "bvh", "motion": "orbits", "build": build, "policy": name}
        record = _harness.point("dynamic", "cuda", width, height, spheres.shape[1], options, frame_ms,
                                walk_ms if walk_ms[0] is not None else None)  # fmt: skip
        record["update_ms"] = summarize(update_ms)
        record["updates"] = {k: kinds.count(k) for k in ("refit", "build") if k in kinds}
        record["update_share"] = sum(update_ms) / sum(frame_ms)
        record["frames_per_s"] = 1e3 / record["frame_ms"]["median"]
        record["cost_ratio"] = cost_ratio
        out.append(record)
    return out


def leaf_sizes(spheres: np.ndarray, width: int, height: int, frames: int, sizes) -> list[dict]:
    """Per largest leaf: both walks' kernel times on the GPU tree of the default quality (the
    tracer's tree replaced by one built with it), records of the parts suite with its SAH cost."""
    basis = Camera().basis(width, height)
    d_spheres = cuda.to_device(spheres)
    out = []
    for walk in ("ray", "packet"):
        with backends.tracer("cuda", spheres, width, height, build="gpu", walk=walk) as tracer:
            for size in sizes:
                builder = cuda_build.Builder(spheres.shape[1], size)
                builder.launch_build(d_spheres)
                tree = builder.tree(builder.read_depth(), 0.0)
                use_tree(tracer, tree)
                wall, kernel = timed_frames(tracer, basis, frames)
                options = {"leaf_size": size, "walk": walk, "timing": "kernel" if kernel else "frame"}
                out.append(
                    _harness.part(
                        "gpu-tree-leaf-walk", "cuda", kernel or wall, spheres=spheres.shape[1], width=width,
                        height=height, options=options,
                        values={"sah": round(tree_cost.sah_cost(tree.to_host().nodes), 3)},
                    )
                )  # fmt: skip
    return out


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--spheres", action="append", type=int, help="default: 1000, 100000, 1000000")
    parser.add_argument("--size", default="1680x1050")
    parser.add_argument("--repeats", type=int, default=51, help="timed GPU builds (and refits) per count")
    parser.add_argument("--leaf-size", type=int, action="append", help="largest leaves to sweep (default 1, 2, 4, 8)")
    parser.add_argument(
        "--quality", action="append", choices=cuda_build.QUALITIES, help="GPU trees to measure (default all)"
    )
    parser.add_argument("--treelet-passes", type=int, default=lbvh.TREELET_PASSES, help="bottom-up passes of treelets")
    parser.add_argument("--anim-frames", type=int, default=40, help="frames of moving spheres per policy")
    parser.add_argument("--anim-dt", type=float, default=0.1, help="seconds of the animation between frames")
    _harness.add_common(parser, frames=15)  # frames per walk
    args = parser.parse_args()
    _harness.check_common(parser, args)
    if args.repeats < 1:
        parser.error(f"--repeats: must be at least 1, got {args.repeats}")
    width, height = (int(v) for v in args.size.split("x"))
    settings = {"treelet_passes": args.treelet_passes, "quality": cuda_build.QUALITY, "leaf_size": cuda_build.LEAF_SIZE}
    with _harness.Records("gpu_build", args, settings) as out:
        for n in args.spheres or [1000, 100_000, 1_000_000]:
            spheres = raybench.random_spheres(n, seed=0).spheres
            host = host_build(spheres, args.repeats)
            for record in host:
                out.write(record)
            qualities = args.quality or list(cuda_build.QUALITIES)
            for record in walks(spheres, width, height, args.frames, qualities, args.treelet_passes):
                out.write(record)
            for quality in qualities:
                timings, figures = gpu_build(spheres, args.repeats, quality, args.treelet_passes)
                figures["sah_over_host"] = round(figures["sah"] / host[0]["values"]["sah"], 4)
                options = {"quality": quality, "treelet_passes": args.treelet_passes}
                for quantity, times in timings.items():
                    out.write(_harness.part(quantity, "cuda", times, spheres=n, options=options,
                                            values=figures if quantity == "gpu-build-wall" else None))  # fmt: skip
            for record in leaf_sizes(spheres, width, height, args.frames, args.leaf_size or [1, 2, 4, 8]):
                out.write(record)
            if args.anim_frames > 0:
                for record in dynamic(spheres, width, height, args.anim_frames, args.anim_dt):
                    out.write(record)
    return 0


if __name__ == "__main__":
    sys.exit(main())
