"""What the embedded cluster's TLS costs a frame: two embedded clusters of --workers cpu workers,
one as raybench makes it (TLS, credentials made for it: raybench.cluster.embedded_security()) and
one on plain TCP (Security()), both started before the first timed frame, then taking turns round
by round (paired), each round --frames frames of raybench.cluster.render (tiles written into the
client's shared block) at each size. One record of the results schema's "parts" suite
(quantity "cluster-frame") a case and size, options naming the case; and Dask's latency of one
empty task on each (quantity "dask-empty-task-latency"), the cost a message pays twice.

    PYTHONPATH=src python benchmarks/cluster_tls.py --size 64x48 --size 1680x1050 --spheres 1000 \\
        --frames 10 --rounds 8 --out benchmarks/results/xeon-2c/cluster-tls/cluster-tls-20261201.jsonl
"""

from __future__ import annotations

import argparse
import sys
import time

import _harness
import numpy as np

import raybench
from raybench import Camera, cluster


def noop():
    return None


def frames(client, scene, width, height, count) -> list[float]:
    cameras = [Camera(position=(0.3 * np.sin(a), 0.0, 0.3 * np.cos(a))) for a in np.linspace(0, 0.5, count)]
    out = []
    for camera in cameras:
        start = time.perf_counter()
        cluster.render(client, scene, camera, width, height, "cpu")
        out.append((time.perf_counter() - start) * 1e3)
    return out


def empty_task(client, count: int = 50) -> float:
    start = time.perf_counter()
    for _ in range(count):
        client.submit(noop, pure=False).result(timeout=60)
    return (time.perf_counter() - start) * 1e3 / count


def main(argv=None) -> int:
    from distributed.security import Security

    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--size", action="append", help="WxH, repeatable (default 1680x1050)")
    parser.add_argument("--spheres", type=int, default=1000)
    parser.add_argument("--workers", type=int, default=2)
    _harness.add_common(parser, frames=10, rounds=8)
    args = parser.parse_args(argv)
    _harness.check_common(parser, args)
    sizes = [tuple(int(v) for v in s.lower().split("x")) for s in args.size or ["1680x1050"]]
    scene = raybench.random_spheres(args.spheres, seed=0)
    raybench.render(scene, width=16, height=8, device="cpu")  # compiled into the cache, for the workers to load
    cases = {"tls": None, "tcp": Security()}  # None: raybench's default, embedded_security()
    settings = {"workers": args.workers, "sizes": args.size, "frames": args.frames, "rounds": args.rounds}
    with _harness.Records("cluster_tls", args, settings) as out:
        running = {name: cluster.Cluster(workers=args.workers, device="cpu", security=s) for name, s in cases.items()}
        try:
            for name, c in running.items():
                c.client.wait_for_workers(args.workers, timeout=120)
                assert c.client.scheduler.address.startswith(f"{name}://"), c.client.scheduler.address
                for width, height in sizes:
                    frames(c.client, scene, width, height, 2)  # warm: renderers, blocks, connections
            for width, height in sizes:
                turns = {
                    name: (lambda c=c, w=width, h=height: frames(c.client, scene, w, h, args.frames))
                    for name, c in running.items()
                }
                for name, ms in _harness.paired(turns, args.rounds).items():
                    options = {"security": name, "workers": args.workers}
                    record = _harness.part("cluster-frame", "cpu", ms, spheres=args.spheres, width=width,
                                           height=height, options=options)  # fmt: skip
                    out.write(record)
            latency = _harness.paired({name: (lambda c=c: empty_task(c.client)) for name, c in running.items()},
                                      args.rounds)  # fmt: skip
            for name, ms in latency.items():
                out.write(_harness.part("dask-empty-task-latency", "cpu", ms, options={"security": name}))
        finally:
            for c in running.values():
                c.close()
    return 0


if __name__ == "__main__":
    sys.exit(main())
