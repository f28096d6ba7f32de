"""raybench's work on Dask workers: one large frame in tiles, or a sequence of
frames, traced across the workers of a Dask cluster and gathered here.

  client       the Dask client, and the embedded cluster it starts or the one
               it joins by address
  tasks        what runs on a worker: its device, its warm renderers, and
               the tasks that trace with them
  work         the jobs: a frame in tiles, a sequence of frames, dealt out
               as tasks and gathered here (work.py says how)
  sharedframe  a frame's image and hits in shared memory, which workers on
               the client's host write their rows into

The benchmark on every machine of a cluster is raybench.bench.machines.
"""

from __future__ import annotations

from .client import HOST, SCHEDULER_ENV, Cluster, connect, default_workers, gpu_count, worker_specs
from .tasks import check_workers
from .work import (
    SequenceOptions,
    ShadingOptions,
    frame_path,
    release,
    render,
    render_sequence,
    tile_rows,
    trace_frames,
)

__all__ = [
    "HOST",
    "SCHEDULER_ENV",
    "SequenceOptions",
    "ShadingOptions",
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
