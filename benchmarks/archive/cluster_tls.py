"""What the embedded cluster's TLS costs a frame: an embedded cluster of --workers cpu workers as
raybench makes it (mutual TLS, credentials made for it: raybench.cluster.embedded_security())
against the same on plain TCP (Security()). Each round starts, for each case in turn (the order
turning round by round), a fresh process with a fresh cluster, which traces 2 untimed frames, then
--frames frames of raybench.cluster.render (tiles written into the client's shared block) at
each size, and Dask's latency of one empty task. One process a round and case: two clusters in
one process were measured first, and the one made first was the slower whichever it was (13 ms
a frame), which a process each avoids. One record of the results schema's "parts" suite
(quantity "cluster-frame") a case and size, options naming the case; the CPU time a frame of all
the cluster's processes, client and workers, a sample a round (quantity "cluster-frame-cpu": what
TLS's work adds, which another job's load on the machine blurs less); and the empty task's
latency (quantity "dask-empty-task-latency"), a message's cost paid twice.

    PYTHONPATH=src:benchmarks python benchmarks/archive/cluster_tls.py --size 64x48 --size 1680x1050 --spheres 1000 \\
        --frames 10 --rounds 8 --out benchmarks/results/xeon-2c/cluster-tls/cluster-tls-20261201.jsonl
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

CASES = ("tls", "tcp")


def noop():
    return None


def cpu_seconds() -> float:
    """CPU time so far of this process (the client, the scheduler, the nannies) and its children (the workers)."""
    import psutil

    family = [psutil.Process(), *psutil.Process().children(recursive=True)]
    return sum(sum(p.cpu_times()[:2]) for p in family)


def frames(client, scene, width, height, count) -> tuple[list[float], float]:
    """count frames: the wall ms of each, and the CPU ms a frame of every process of the cluster."""
    cameras = [Camera(position=(0.3 * np.sin(a), 0.0, 0.3 * np.cos(a))) for a in np.linspace(0, 0.5, count)]
    out = []
    cpu = cpu_seconds()
    for camera in cameras:
        start = time.perf_counter()
        cluster.render(client, scene, camera, width, height, "cpu")
        out.append((time.perf_counter() - start) * 1e3)
    return out, (cpu_seconds() - cpu) * 1e3 / count


def empty_task(client, count: int = 50) -> float:
    start = time.perf_counter()
    for _ in range(count):
        client.submit(noop, pure=False).result(timeout=60)
    return (time.perf_counter() - start) * 1e3 / count


def child(case: str, sizes, spheres: int, workers: int, count: int) -> dict:
    """One round of one case, in this process: {size: frame ms, "empty": ms}."""
    from distributed.security import Security

    scene = raybench.random_spheres(spheres, seed=0)
    with cluster.Cluster(workers=workers, device="cpu", security=None if case == "tls" else Security()) as c:
        c.client.wait_for_workers(workers, timeout=120)
        assert c.client.scheduler.address.startswith(f"{case}://"), c.client.scheduler.address
        out = {}
        for width, height in sizes:
            frames(c.client, scene, width, height, 2)  # warm: renderers, the block, connections
            out[f"{width}x{height}"], out[f"cpu-{width}x{height}"] = frames(c.client, scene, width, height, count)
        out["empty"] = empty_task(c.client)
        return out


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--size", action="append", help="WxH, repeatable (default 1680x1050)")
    parser.add_argument("--spheres", type=int, default=1000)
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--child", choices=CASES, help=argparse.SUPPRESS)
    _harness.add_common(parser, frames=10, rounds=8)
    args = parser.parse_args(argv)
    _harness.check_common(parser, args)
    sizes = [tuple(int(v) for v in s.lower().split("x")) for s in args.size or ["1680x1050"]]
    if args.child:
        print(json.dumps(child(args.child, sizes, args.spheres, args.workers, args.frames)))
        return 0
    raybench.render(raybench.random_spheres(3), width=16, height=8, device="cpu")  # compiled into the cache

    def one_round(case: str) -> list[dict]:
        argv = [sys.executable, __file__, "--child", case, "--spheres", str(args.spheres), "--workers",
                str(args.workers), "--frames", str(args.frames), *(f"--size={w}x{h}" for w, h in sizes)]  # fmt: skip
        done = subprocess.run(argv, env=os.environ, capture_output=True, text=True, timeout=600, check=True)
        return [json.loads(done.stdout.strip().splitlines()[-1])]

    rounds = _harness.paired({case: (lambda case=case: one_round(case)) for case in CASES}, args.rounds)
    settings = {"workers": args.workers, "sizes": args.size, "frames": args.frames, "rounds": args.rounds}
    with _harness.Records("cluster_tls", args, settings) as out:
        for width, height in sizes:
            for case, got in rounds.items():
                ms = [t for r in got for t in r[f"{width}x{height}"]]
                options = {"security": case, "workers": args.workers}
                out.write(_harness.part("cluster-frame", "cpu", ms, spheres=args.spheres, width=width,
                                        height=height, options=options))  # fmt: skip
                cpu = [r[f"cpu-{width}x{height}"] for r in got]  # a round's CPU ms a frame, all processes
                out.write(_harness.part("cluster-frame-cpu", "cpu", cpu, spheres=args.spheres, width=width,
                                        height=height, options=options))  # fmt: skip
        for case, got in rounds.items():
            out.write(_harness.part("dask-empty-task-latency", "cpu", [r["empty"] for r in got],
                                    options={"security": case}))  # fmt: skip
    return 0


if __name__ == "__main__":
    sys.exit(main())
