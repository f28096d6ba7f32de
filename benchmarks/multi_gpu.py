"""Throughput of 1..N raybench.cluster workers (issue 17): one record of the
results schema's "multi-gpu" suite per (job, workers) (options job "sequence"
or "frame", delivery as below; `raybench report` gives each job's efficiency
against linear, throughput with N workers / (N x with one)), and the terms
job's terms as records of its "parts" suite (quantity "cluster-" and the term).

Jobs:
  orbit        --orbit frames of an orbit at --orbit-size, traced in tasks of
               frames (cluster.trace_frames: each frame traced into the worker's
               warm tracer, then its hits counted), nothing sent back but the counts
  orbit-png    the same frames through cluster.render_sequence: PNGs encoded
               on the workers, written here (what `raybench render --path` does)
  frame        one --frame sized frame in tiles (cluster.render): the workers
               write their rows into the frame, made here in shared memory and
               kept from frame to frame; the first frame (the block made here,
               the workers' mappings of it) is timed apart (first_s), after a
               warming frame that sends its tiles
  frame-sent   the same frame with every tile sent to the client and assembled
               here (cluster.render(shared=False): a cluster across machines)
  terms        the scaling model's terms on this cluster (docs/notes/scaling.md): the
               scene's broadcast, an empty task's cost, a tile's transfer, the
               assembly of a sent frame, a frame's shared block made here, and a
               frame's rows written into shared memory by the workers, into a
               new block and into one kept from frame to frame

Every job is warmed first (each worker compiles, builds and uploads once),
and timed over --frames runs.

    PYTHONPATH=src python benchmarks/multi_gpu.py --device cuda --workers 1 --workers 2 \\
        --spheres 100000 --frame 8192x8192 --orbit 240 --orbit-size 1680x1050 --out multi_gpu.jsonl
"""

from __future__ import annotations

import argparse
import math
import os
import sys
import tempfile
import time

import _harness
import numpy as np

import raybench
from raybench import Camera, camera_path, cluster
from raybench.cluster import sharedframe, work


def array_of(nbytes: int):
    return np.ones(nbytes, np.uint8)


def nothing():
    return None


def shm_free() -> int | None:
    try:
        stat = os.statvfs(sharedframe.SHM_DIR)
    except OSError:
        return None
    return stat.f_bavail * stat.f_frsize


def tile_arrays(first: int, end: int, width: int):
    """A tile's image and hits, as a worker's tracer leaves them."""
    return np.ones((end - first, width, 3), np.uint8), np.ones((end - first, width), np.int32)


def made_only(first: int, end: int, width: int) -> None:
    tile_arrays(first, end, width)


def written(address, first: int, end: int, width: int) -> bool:
    return sharedframe.write_rows(address, first, *tile_arrays(first, end, width))


def options(args) -> dict:
    """The device options of every job: the walk, and the cpu's threads a worker."""
    return {"accel": args.accel, **({"threads": args.threads} if args.threads else {})}


def parse_size(text: str) -> tuple[int, int]:
    w, h = text.lower().split("x")
    return int(w), int(h)


def timed(f, repeat: int) -> list[float]:
    """The seconds of each of `repeat` calls of f."""
    return [ms / 1e3 for ms in _harness.timings(f, repeat)]


def orbit_job(client, args, scene, workers) -> dict:
    width, height = parse_size(args.orbit_size)
    cameras = camera_path.orbit(scene.camera or Camera(position=(0, 0, -1), look_at=(0, 0, 2)), args.orbit)
    per_task = args.frames_per_task or min(
        work.MAX_FRAMES_PER_TASK, math.ceil(len(cameras) / (workers * work.TASKS_PER_WORKER))
    )

    def go(frames=cameras):
        cluster.trace_frames(client, scene, frames, width, height, args.device, per_task, **options(args))

    go(cameras[: workers * per_task])  # warm: a task on every worker
    seconds = timed(go, args.frames)
    return {"width": width, "height": height, "frames": len(cameras), "tasks": math.ceil(len(cameras) / per_task),
            "seconds": seconds}  # fmt: skip


def orbit_png_job(client, args, scene, workers) -> dict:
    width, height = parse_size(args.orbit_size)
    cameras = camera_path.orbit(scene.camera or Camera(position=(0, 0, -1), look_at=(0, 0, 2)), args.orbit)
    with tempfile.TemporaryDirectory() as warm:
        cluster.render_sequence(client, scene, cameras[:workers], warm, width, height, args.device, **options(args))
    seconds = []
    for _ in range(args.frames):
        with tempfile.TemporaryDirectory() as out:
            start = time.perf_counter()
            cluster.render_sequence(client, scene, cameras, out, width, height, args.device, **options(args))
            seconds.append(time.perf_counter() - start)
    return {"width": width, "height": height, "frames": len(cameras), "seconds": seconds}


def frame_job(client, args, scene, workers, shared=True) -> dict:
    from distributed import get_task_stream

    width, height = parse_size(args.frame)
    rows = args.tile or cluster.tile_rows(height, workers)

    def go():
        return cluster.render(
            client, scene, None, width, height, args.device, rows=rows, shared=shared, **options(args)
        )

    # warm: every worker that got a tile compiled and built its tree; with
    # tiles sent, so that the shared path's first frame is timed on its own
    cluster.release(client)
    cluster.render(client, scene, None, width, height, args.device, rows=rows, shared=False, **options(args))
    first_s = timed(go, 1)[0]  # shared: the block made here, and each worker's mapping of it
    with get_task_stream(client) as stream:
        seconds = timed(go, args.frames)
    pool = work.pool(client)
    return {"width": width, "height": height, "frames": 1, "rows": rows, "tasks": math.ceil(height / rows),
            "shared": shared and pool.made > 0, "first_s": first_s, "seconds": seconds,
            "blocks_made": pool.made,  # 1: every repeat reused the first frame's block
            "workers_mapped": sorted(client.run(sharedframe.mapped_blocks).values()),
            **busy_in_tasks(stream.data, args.frames, sum(seconds))}  # fmt: skip


def busy_in_tasks(stream, frames: int, wall_s: float) -> dict:
    """Where a frame's time went, from the scheduler's task stream: each worker's
    time computing its tiles, a frame; the busiest worker's; and what is left of
    the frame outside the busiest worker's tiles (the scheduler's rounds, the
    results' travel, the client's lease of the block and the Frame)."""
    busy = {}
    for task in stream:
        if "_tile" in str(task["key"]):
            for part in task["startstops"]:
                if part["action"] == "compute":
                    busy[task["worker"]] = busy.get(task["worker"], 0.0) + part["stop"] - part["start"]
    per_frame = sorted(round(1e3 * b / frames, 2) for b in busy.values())
    busiest = max(per_frame, default=0.0)
    return {"tile_ms_per_frame": per_frame, "outside_tiles_ms_per_frame": round(1e3 * wall_s / frames - busiest, 2)}


def frame_sent_job(client, args, scene, workers) -> dict:
    return frame_job(client, args, scene, workers, shared=False)


def terms_job(client, args, scene, workers) -> dict:
    """The scaling model's terms, each the median of --repeat."""
    width, height = parse_size(args.frame)
    # a key of its own each time (hash=False), so that nothing is found on the workers already
    broadcast = timed(lambda: client.scatter(scene, broadcast=True, hash=False).release(), args.frames)
    n = 200
    empty = timed(lambda: client.gather([client.submit(nothing, pure=False) for _ in range(n)]), args.frames)
    rows = cluster.tile_rows(height, workers)
    tile_bytes = rows * width * 7  # RGB bytes and an int32 hit a pixel
    tiles = 16
    fetched = timed(
        lambda: client.gather([client.submit(array_of, tile_bytes, pure=False) for _ in range(tiles)]), args.frames
    )
    made = timed(lambda: client.gather([client.submit(lambda b: array_of(b).sum(), tile_bytes, pure=False)
                                        for _ in range(tiles)]), args.frames)  # fmt: skip
    image = np.zeros((height, width, 3), np.uint8)
    assembly = timed(lambda: np.copyto(image, np.ones_like(image)), args.frames)
    # The shared path's cost a frame: every tile's rows written by the workers
    # in parallel into a block made here, less the same tasks making their rows
    # only. First into a new block (made here, mapped afresh by each worker: a
    # session's first frame of a size), then into the block kept from frame to
    # frame (every later frame of that size).
    bands = [(a, min(a + rows, height)) for a in range(0, height, rows)]

    def shared_frame(pool):
        lease = pool.lease(width, height)
        try:
            done = client.gather([client.submit(written, lease.address, a, b, width, pure=False) for a, b in bands])
        finally:
            lease.end()
        if not all(done):
            raise RuntimeError("a worker could not write into the shared block (another host? /dev/shm full?)")

    def new_block():
        client.run(sharedframe.forget)
        pool = sharedframe.Pool()
        try:
            start = time.perf_counter()
            shared_frame(pool)
            return time.perf_counter() - start
        finally:
            pool.close()

    # None where the host has no room in /dev/shm for the frame (the frame job then sends its tiles)
    first = made = resident = None
    if sharedframe.fits(width, height):
        made = timed(lambda: sharedframe.Block(width, height).close(), args.frames)
        first = [new_block() for _ in range(args.frames)]
        kept = sharedframe.Pool()
        try:
            shared_frame(kept)
            resident = timed(lambda: shared_frame(kept), args.frames)
        finally:
            kept.close()
            client.run(sharedframe.forget)
    unshared = timed(
        lambda: client.gather([client.submit(made_only, a, b, width, pure=False) for a, b in bands]), args.frames
    )
    # each term a difference of medians or a share of one: one figure, not a run of samples
    return {
        "terms_ms": {
            "broadcast": _harness.median(broadcast) * 1e3,
            "empty_task": _harness.median(empty) * 1e3 / n,
            "tile_transfer": max(0.0, (_harness.median(fetched) - _harness.median(made)) * 1e3 / tiles),
            "assembly_per_frame": _harness.median(assembly) * 1e3 * 7 / 3,
            "block_made": None if made is None else _harness.median(made) * 1e3,
            "shared_first_per_frame": None
            if first is None
            else max(0.0, (_harness.median(first) - _harness.median(unshared)) * 1e3),
            "resident_write_per_frame": None
            if resident is None
            else max(0.0, (_harness.median(resident) - _harness.median(unshared)) * 1e3),
        },
        "broadcast_bytes": int(scene.spheres.nbytes),
        "tile_transfer_bytes": tile_bytes,
        "shm_free_bytes": shm_free(),
    }


JOBS = {"orbit": orbit_job, "orbit-png": orbit_png_job, "frame": frame_job, "frame-sent": frame_sent_job,
        "terms": terms_job}  # fmt: skip


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--device", default="cpu", choices=("cpu", "cuda"))
    parser.add_argument("--workers", type=int, action="append", help="worker counts to run (repeat; default 1 2)")
    parser.add_argument("--job", action="append", choices=tuple(JOBS), help="jobs to run (repeat; default all)")
    parser.add_argument("--spheres", type=int, default=100_000)
    parser.add_argument("--accel", default="bvh", choices=("bvh", "none"))
    parser.add_argument("--threads", type=int, help="cpu: threads a worker (default: the cores shared out)")
    parser.add_argument("--frame", default="8192x8192", help="the large frame's size")
    parser.add_argument("--tile", type=int, help="the large frame's tile rows (default cluster.tile_rows)")
    parser.add_argument("--orbit", type=int, default=240, help="frames of the orbit")
    parser.add_argument("--orbit-size", default="1680x1050")
    parser.add_argument("--frames-per-task", type=int, help="the orbit's frames a task (default as render_sequence)")
    _harness.add_common(parser, frames=3)
    parser.add_argument("--repeat", dest="frames", type=int, help=argparse.SUPPRESS)  # its name before --frames
    args = parser.parse_args(argv)
    _harness.check_common(parser, args)
    scene = raybench.random_spheres(args.spheres, seed=0)
    jobs = args.job or list(JOBS)
    with _harness.Records("multi_gpu", args, {"jobs": jobs}) as out:
        for _ in range(args.rounds):
            for workers in args.workers or [1, 2]:
                with cluster.Cluster(workers=workers, device=args.device) as running:
                    running.client.wait_for_workers(workers)
                    for job in jobs:
                        for record in records_of(job, JOBS[job](running.client, args, scene, workers), args, workers):
                            out.write(record)
    return 0


# job -> the suite's job and how its frames came back
DELIVERY = {"orbit": ("sequence", "counts"), "orbit-png": ("sequence", "png"), "frame": ("frame", "shared"),
            "frame-sent": ("frame", "sent")}  # fmt: skip


def records_of(job: str, got: dict, args, workers: int) -> list[dict]:
    """A job's records: a point of the multi-gpu suite (ms a frame of each run), or the terms."""
    if job == "terms":
        return [
            _harness.part(f"cluster-{term.replace('_', '-')}", args.device, [ms], spheres=args.spheres,
                          options={"workers": workers}, values={"bytes": got.get(f"{term}_bytes")})
            for term, ms in got["terms_ms"].items()
            if ms is not None and ms > 0
        ]  # fmt: skip
    kind, delivery = DELIVERY[job]
    if kind == "frame" and not got.get("shared"):  # no room in /dev/shm: the tiles were sent
        delivery = "sent"
    opts = {**options(args), "workers": workers, "job": kind, "delivery": delivery}
    if kind == "sequence":
        opts["frames"] = got["frames"]
    frame_ms = [s * 1e3 / got["frames"] for s in got["seconds"]]
    record = _harness.point("multi-gpu", args.device, got["width"], got["height"], args.spheres, opts, frame_ms)
    record["frames_per_s"] = 1e3 / record["frame_ms"]["median"]
    if "first_s" in got:
        record["first_frame_s"] = got["first_s"]
    record.update({k: got[k] for k in ("tasks", "blocks_made", "workers_mapped", "tile_ms_per_frame",
                                       "outside_tiles_ms_per_frame") if k in got})  # fmt: skip
    return [record]


if __name__ == "__main__":
    sys.exit(main())
