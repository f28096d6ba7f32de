"""The BVH built on the GPU through wgpu (backends.wgpu.build) against the
host's binned SAH build (raybench.bvh), on random_spheres(n, seed=0), as
records of the results schema: the builds and refits in its "parts" suite
(quantity "bvh-build" for the host's; "gpu-build", "gpu-build-wall",
"gpu-build-" and a step, "gpu-refit", "gpu-refit-wall", options naming the
quality and the sort's bits a round, the trees' SAH costs, depths and rows
as figures), the walks on each tree in its "scaling" suite (option build):

- the GPU build's time, warm: GPU timestamps around its one compute pass
  (--repeats builds), each step's time (the steps then in a pass each,
  timestamps around each: a pass more per step than a build has), and the
  wall time from the submission to the depth read back (the tree ready to
  walk, Python's encoding and the map included);
- the refit's time (the boxes from the same spheres, the tree kept), by timestamps;
- the host build's time (compiled code, every core, as raybench reports it);
- the SAH cost of both trees (raybench.bvh.cost), their depths and rows;
- with --frames > 0, the walk's time on each tree (Tracer.timed_trace, the
  default camera at --size), --frames frames (0: no walk).

Without timestamps (an adapter without "timestamp-query") only the wall
times are recorded.

    python benchmarks/wgpu_build.py --out out.jsonl [--adapter NAME] [--spheres 1000 --spheres 100000]
        [--repeats 21] [--quality sah --quality lbvh] [--frames 11] [--split-bits 1 --split-bits 3]

The same figures for numba-cuda's build: benchmarks/gpu_build.py.
"""

import argparse
import sys
import time

import _harness
import numpy as np

import raybench
from raybench import Camera, backends, bvh
from raybench.backends.wgpu import adapters, compute
from raybench.backends.wgpu import build as gpu_build
from raybench.backends.wgpu.tracer import timestamp_period
from raybench.bvh import cost as tree_cost


class Clock:
    """GPU timestamps around compute passes: begin_end(i) is the
    timestamp_writes of pass i; read() their ms once the work is submitted."""

    def __init__(self, device, passes: int):
        import wgpu

        self.device, self.passes = device, passes
        self.period = timestamp_period(device) if "timestamp-query" in device.features else None
        if self.period is None:
            return
        self.queries = device.create_query_set(type="timestamp", count=2 * passes)
        self.resolved = device.create_buffer(
            size=16 * passes, usage=wgpu.BufferUsage.QUERY_RESOLVE | wgpu.BufferUsage.COPY_SRC
        )

    def begin_end(self, i: int):
        if self.period is None:
            return None
        return {"query_set": self.queries, "beginning_of_pass_write_index": 2 * i, "end_of_pass_write_index": 2 * i + 1}

    def resolve(self, encoder) -> None:
        if self.period is not None:
            encoder.resolve_query_set(self.queries, 0, 2 * self.passes, self.resolved, 0)

    def read(self) -> list[float] | None:
        if self.period is None:
            return None
        ticks = np.frombuffer(self.device.queue.read_buffer(self.resolved), np.uint64).reshape(-1, 2)
        return [float(end - begin) * self.period / 1e6 for begin, end in ticks]


def gpu_build_times(device, spheres: np.ndarray, repeats: int, quality: str, primitive: str = "sphere") -> dict:
    """spheres: the scene's buffer of that kind of primitive (benchmarks/mesh_build.py times triangles)."""
    import wgpu

    n = spheres.shape[1]
    rows = compute.SCENE_ROWS[primitive](spheres)
    buffer = device.create_buffer_with_data(data=rows.tobytes(), usage=wgpu.BufferUsage.STORAGE)
    kernels = gpu_build.Kernels(device, primitive)
    builder = gpu_build.Builder(device, buffer, n, quality=quality, kernels=kernels)
    for _ in range(3):  # the pipelines compiled by the driver, warm
        builder.run(builder.encode_build)
    steps = builder.steps()
    whole, per_step, wall, refit = Clock(device, 1), Clock(device, len(steps)), [], []
    times = {"build": [], "refit": [], **{s: [] for s in steps}}
    for _ in range(repeats):
        start = time.perf_counter()
        stats = builder.run(lambda e: (builder.encode(e, [d for s in steps.values() for d in s], whole.begin_end(0)),
                                       whole.resolve(e)))  # fmt: skip
        wall.append((time.perf_counter() - start) * 1e3)
        times["build"].append((whole.read() or [None])[0])
        start = time.perf_counter()
        builder.run(lambda e: ([builder.encode(e, d, per_step.begin_end(i)) for i, d in enumerate(steps.values())],
                               per_step.resolve(e)))  # fmt: skip
        for name, ms in zip(steps, per_step.read() or [None] * len(steps)):
            times[name].append(ms)
        start = time.perf_counter()
        builder.run(lambda e: (builder.encode_refit(e, whole.begin_end(0)), whole.resolve(e)))
        refit.append((time.perf_counter() - start) * 1e3)
        times["refit"].append((whole.read() or [None])[0])
    tree = builder.to_host(stats.depth)
    timings = {"gpu-build": times["build"], "gpu-build-wall": wall, "gpu-refit": times["refit"],
               "gpu-refit-wall": refit, **{f"gpu-build-{s}": times[s] for s in steps}}  # fmt: skip
    figures = {"depth": stats.depth, "rows": tree.node_count, "rows_walked": stats.rows,
               "sah": round(tree_cost.sah_cost(tree.nodes), 3),
               "dispatches": sum(len(s) for s in steps.values())}  # fmt: skip
    # None where the adapter has no timestamps
    return {name: ms for name, ms in timings.items() if ms and ms[0] is not None}, figures


def host_build(spheres: np.ndarray, repeats: int) -> dict:
    """The host's builds, a record of the parts suite (its tree's SAH cost among its figures)."""
    bvh.compile_builder()
    times = [bvh.build(spheres).build_s * 1e3 for _ in range(max(3, repeats // 5))]
    tree = bvh.build(spheres)
    values = {"depth": tree.depth, "rows": tree.node_count, "sah": round(tree_cost.sah_cost(tree.nodes), 3)}
    return _harness.part("bvh-build", "cpu", times, spheres=spheres.shape[1], values=values)


def walk(adapter, spheres, width: int, height: int, frames: int, build: str) -> dict:
    """The walk on the tree built where `build` says: a point of the scaling suite."""
    basis = Camera().basis(width, height)
    with backends.tracer("wgpu", spheres, width, height, adapter=adapter, build=build) as tracer:
        tracer.trace(basis)
        kernel = []
        wall = _harness.timings(lambda: kernel.append(tracer.timed_trace(basis)), frames)
        kernel = kernel if kernel[0] is not None else None
        return _harness.point("scaling", "wgpu", width, height, spheres.shape[1], {"accel": "bvh", "build": build},
                              wall, kernel, build_s=tracer.build_s)  # fmt: skip


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--adapter", help="the wgpu adapter (default: the best GPU; name a CPU driver to use it)")
    parser.add_argument("--spheres", action="append", type=int, help="default: 1000, 100000, 1000000")
    parser.add_argument("--quality", action="append", choices=gpu_build.QUALITIES, help="default all")
    parser.add_argument("--repeats", type=int, default=21, help="timed builds per count")
    parser.add_argument("--size", default="1680x1050", help="the walk's frame")
    parser.add_argument(
        "--split-bits",
        action="append",
        type=int,
        choices=(1, 2, 3),
        help=f"the sort's bits a round in its tiles (default {gpu_build.SPLIT_BITS}); repeat to compare",
    )
    _harness.add_common(parser, frames=11)  # frames per walk; 0: no walk
    args = parser.parse_args()
    walk_frames = args.frames
    args.frames = max(args.frames, 1)  # 0 is allowed here: no walk
    _harness.check_common(parser, args)
    if args.repeats < 1:
        parser.error(f"--repeats: must be at least 1, got {args.repeats}")
    width, height = (int(v) for v in args.size.split("x"))
    adapter = adapters.choose(args.adapter)
    device = adapters.request_device(adapter)
    splits = args.split_bits or [gpu_build.SPLIT_BITS]
    name = str(adapter.describe().get("name", ""))[:100]
    with _harness.Records("wgpu_build", args, {"adapter": name, "split_bits": splits}) as out:
        for n in args.spheres or [1000, 100_000, 1_000_000]:
            spheres = raybench.random_spheres(n, seed=0).spheres
            host = host_build(spheres, args.repeats)
            out.write(host)
            if walk_frames > 0:
                host_walk = walk(args.adapter, spheres, width, height, walk_frames, "host")
                out.write(host_walk)
            for quality, bits in [(q, b) for q in args.quality or gpu_build.QUALITIES for b in splits]:
                gpu_build.SPLIT_BITS = bits
                gpu_build.source.cache_clear()
                timings, figures = gpu_build_times(device, spheres, args.repeats, quality)
                figures["sah_over_host"] = round(figures["sah"] / host["values"]["sah"], 4)
                options = {"quality": quality, "split_bits": bits, "adapter": name}
                for quantity, times in timings.items():
                    out.write(_harness.part(quantity, "wgpu", times, spheres=n, options=options,
                                            values=figures if quantity == "gpu-build-wall" else None))  # fmt: skip
                if walk_frames > 0 and quality == gpu_build.lbvh.QUALITY and bits == splits[0]:
                    out.write(walk(args.adapter, spheres, width, height, walk_frames, "gpu"))  # the Tracer's quality
    return 0


if __name__ == "__main__":
    sys.exit(main())
