"""Where a frame's time goes inside a Dask worker, against a plain process:
issue 17's probe saw 4.1 ms a frame in a worker's task loop where a plain
process took 2.5 ms. One record of the results schema's "parts" suite per
case (quantity "dask-" and the case), a sample a round: the ms a frame of a
loop of --frames frames of one warm Renderer (render(camera), which copies
the image and the hits out of the tracer's buffers, then hits.max(), as the
probe's loop):

  plain            this loop in a fresh process, raybench's environment
  plain-malloc     the same with MALLOC_TRIM_THRESHOLD_=65536, which a Dask
                   Nanny puts in its worker's environment
  worker           the loop as one task on a raybench.cluster worker (no
                   MALLOC_TRIM_THRESHOLD_, one thread)
  worker-dask-env  on a worker with Dask's default environment (the variable set)
  worker-noprofile raybench's worker with Dask's statistical profiler off
  copy / copy-malloc   the loop's copies alone (np.copy of a frame's image and
                   hits, then hits.max()), without and with the variable
  empty-task       Dask's cost of one task: a no-op submitted and waited for,
                   one at a time (latency) and 400 at once (per task), on
                   each worker case's cluster

    PYTHONPATH=src:benchmarks python benchmarks/archive/dask_overhead.py --device cpu --size 1680x1050 --spheres 1000 \\
        --out out.jsonl
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import time

import _harness
import numpy as np

import raybench
from raybench import Camera, cluster

MALLOC = {"MALLOC_TRIM_THRESHOLD_": "65536"}


def loop(scene, width, height, device, frames, rounds, accel) -> list[float]:
    """ms a frame of each round: render (with its copies), then hits.max()."""
    with raybench.Renderer(scene, width, height, device=device, accel=accel) as renderer:
        cameras = [Camera(position=(0.3 * np.sin(a), 0.0, 0.3 * np.cos(a))) for a in np.linspace(0, 0.5, frames)]
        renderer.render(cameras[0]).hits.max()  # compiled, uploaded
        out = []
        for _ in range(rounds):
            start = time.perf_counter()
            for camera in cameras:
                renderer.render(camera).hits.max()
            out.append((time.perf_counter() - start) * 1e3 / frames)
        return out


def copies(width, height, frames, rounds) -> list[float]:
    image = np.zeros((height, width, 3), np.uint8)
    hits = np.zeros((height, width), np.int32)
    out = []
    for _ in range(rounds + 1):
        start = time.perf_counter()
        for _ in range(frames):
            image.copy()
            hits.copy().max()
        out.append((time.perf_counter() - start) * 1e3 / frames)
    return out[1:]


def noop():
    return None


def in_process(args, env: dict, what: str) -> list[float]:
    """The loop (or the copies) in a fresh process with env added."""
    argv = [sys.executable, __file__, "--child", what, "--device", args.device, "--size", args.size]
    argv += ["--spheres", str(args.spheres), "--frames", str(args.frames), "--rounds", str(args.rounds)]
    argv += ["--accel", args.accel]
    done = subprocess.run(argv, env={**os.environ, **env}, capture_output=True, text=True, check=True)
    return json.loads(done.stdout.strip().splitlines()[-1])


def on_worker(args, scene, worker_env: dict | None, config: dict | None) -> list[float]:
    """The loop as one task on a one-worker cluster: raybench's, with
    worker_env added to its workers' environment and config to their Dask config."""
    from distributed import Client, Scheduler, SpecCluster

    specs = cluster.worker_specs(args.device, 1)
    for spec in specs.values():
        spec["options"]["env"].update(worker_env or {})
        if config:
            spec["options"]["config"] = config
    with (
        SpecCluster(
            scheduler={"cls": Scheduler, "options": {"host": cluster.HOST, "dashboard_address": f"{cluster.HOST}:0"}},
            workers=specs,
            silence_logs=40,
        ) as spec_cluster,
        Client(spec_cluster) as client,
    ):
        task = client.submit(
            loop, scene, args.width, args.height, args.device, args.frames, args.rounds, args.accel, pure=False
        )
        result = task.result()
        # the empty task's cost, on this cluster
        start = time.perf_counter()
        for _ in range(100):
            client.submit(noop, pure=False).result()
        latency = (time.perf_counter() - start) * 1e3 / 100
        start = time.perf_counter()
        client.gather(client.map(lambda i: None, range(400), pure=False))
        each = (time.perf_counter() - start) * 1e3 / 400
        return result, latency, each


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--device", default="cpu")
    parser.add_argument("--size", default="1680x1050")
    parser.add_argument("--spheres", type=int, default=1000)
    parser.add_argument("--accel", default="bvh")
    parser.add_argument("--child", help=argparse.SUPPRESS)
    _harness.add_common(parser, frames=20, rounds=5)
    args = parser.parse_args(argv)
    _harness.check_common(parser, args)
    args.width, args.height = (int(v) for v in args.size.lower().split("x"))
    scene = raybench.random_spheres(args.spheres, seed=0)
    if args.child == "loop":
        print(json.dumps(loop(scene, args.width, args.height, args.device, args.frames, args.rounds, args.accel)))
        return 0
    if args.child == "copy":
        print(json.dumps(copies(args.width, args.height, args.frames, args.rounds)))
        return 0
    fields = {"spheres": args.spheres, "width": args.width, "height": args.height, "options": {"accel": args.accel}}
    with _harness.Records("dask_overhead", args, {"device": args.device}) as out:
        processes = (("copy", {}, "copy"), ("copy-malloc", MALLOC, "copy"), ("plain", {}, "loop"),
                     ("plain-malloc", MALLOC, "loop"))  # fmt: skip
        for case, env, what in processes:
            out.write(_harness.part(f"dask-{case}", args.device, in_process(args, env, what), **fields))
        for case, env, config in (
            ("worker", None, None),
            ("worker-dask-env", MALLOC, None),
            ("worker-noprofile", None, {"distributed.worker.profile.enabled": False}),
        ):
            ms, latency, each = on_worker(args, scene, env, config)
            out.write(_harness.part(f"dask-{case}", args.device, ms, **fields))
            tasks = {"options": {"cluster": case}}
            out.write(_harness.part("dask-empty-task-latency", args.device, [latency], **tasks))
            out.write(_harness.part("dask-empty-task", args.device, [each], **tasks))
    return 0


if __name__ == "__main__":
    sys.exit(main())
