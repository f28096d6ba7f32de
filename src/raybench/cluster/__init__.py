"""raybench's work on Dask workers: one large frame in tiles, or a sequence of
frames, traced across the workers of a Dask cluster and gathered here.

  work         the cluster, what a worker keeps, and the jobs (work.py says how)
  sharedframe  a frame's image and hits in shared memory, which workers on
               the client's host write their rows into

The benchmark on every machine of a cluster is raybench.bench.machines.
"""

from __future__ import annotations

from .work import (
    HOST,
    SCHEDULER_ENV,
    Cluster,
    check_workers,
    connect,
    default_workers,
    frame_path,
    gpu_count,
    release,
    render,
    render_sequence,
    tile_rows,
    trace_frames,
    worker_specs,
)

__all__ = [
    "HOST",
    "SCHEDULER_ENV",
    "Cluster",
    "check_workers",
    "connect",
    "default_workers",
    "frame_path",
    "gpu_count",
    "release",
    "render",
    "render_sequence",
    "tile_rows",
    "trace_frames",
    "worker_specs",
]
