"""raybench's work on Dask workers: one large frame in tiles, or a sequence of
frames, traced across the workers of a Dask cluster and gathered here.

Dask does the distribution (scatter, scheduling, retries when a worker dies);
this module decides what a job's tasks are, deals them out and gathers what
they make (raybench.cluster.client starts or joins the cluster, and
raybench.cluster.tasks is what a worker runs):

- A task is a band of rows of one frame (a tile: bit for bit the rows of the
  whole frame's render, on cpu and cuda) or a run of whole frames of a sequence (their PNGs,
  encoded on the worker).
- A tile's rows do not travel where they need not: the client makes the frame
  in shared memory (raybench.cluster.sharedframe) and a worker on its host writes its
  rows there; a worker on another host sends them through Dask. The client
  keeps that memory from frame to frame of one size (a sharedframe.Pool per
  client, let go by release(client) or Cluster.close()), with its pages
  resident, and the workers keep their mappings of it.
"""

from __future__ import annotations

import contextlib
import math
import time
import weakref
from collections import OrderedDict
from collections.abc import Callable, Iterable
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .. import sequence
from ..backends.limits import PIXEL_BYTES, check_fits
from ..camera import Camera
from ..errors import RaybenchError, one_line
from ..host import host_available_bytes
from ..render import PNG_LEVEL, Frame
from ..scene import Scene
from ..sequence import frame_path
from . import sharedframe
from .tasks import KEEP_RENDERERS, _frames, _hit_counts, _tile, check_workers

# The BVH's packets are 8 rows high (backends.cpu.PACKET_H): a tile starts on one.
TILE_ALIGN = 8
# Tasks a worker gets of one job, by default: enough that a slow or lost
# worker's share is made up by the others, few enough that the scheduler's
# cost per task (docs/notes/scaling.md) stays small beside the tracing.
TASKS_PER_WORKER = 4
# The most frames a task of a sequence traces, so progress is seen often.
MAX_FRAMES_PER_TASK = 60
# How often a task (a tile, a run of frames) is sent again when the workers it was on are lost
# with it, and how long the client waits, each time, for a worker to trace it (a nanny restarts a
# killed worker, in a few seconds on the machines measured).
LOST_RETRIES = 3
RESTART_WAIT_S = 60.0
# How long render() trusts its last answer of which workers there are and
# what device each has (about the interval at which a Dask client refreshes
# its own view of the scheduler).
WORKERS_FRESH_S = 2.0


@dataclass(frozen=True)
class ShadingOptions:
    """How a job's frames are shaded, as raybench.render() takes it:
    shading "thesis" or "whitted", and Whitted's depth and shadow_samples
    (None: render()'s defaults). One record, so that a job's functions keep
    to a short argument list."""

    shading: str = "thesis"
    depth: int | None = None
    shadow_samples: int | None = None


@dataclass(frozen=True)
class SequenceOptions:
    """How render_sequence deals out, encodes and reports its frames:
    frames_per_task frames a task (None: about TASKS_PER_WORKER tasks a
    worker, at most MAX_FRAMES_PER_TASK frames each), each PNG deflated at
    zlib's png_level, and on_frame(number, path) called for every frame."""

    frames_per_task: int | None = None
    on_frame: Callable[[int, Path], None] | None = None
    png_level: int = PNG_LEVEL


def _shading(shading, options: dict) -> ShadingOptions:
    """shading as a record (a name alone: that shading with its defaults);
    depth or shadow_samples among the device's options is refused, in one
    line, rather than failing on a worker."""
    misplaced = sorted({"depth", "shadow_samples"} & options.keys())
    if misplaced:
        them = "them" if len(misplaced) > 1 else "it"
        raise RaybenchError(f"{', '.join(misplaced)}: give {them} in shading=cluster.ShadingOptions(...)")
    if isinstance(shading, str):
        return ShadingOptions(shading)
    if not isinstance(shading, ShadingOptions):
        raise RaybenchError(f"shading: must be a name or a cluster.ShadingOptions, got {type(shading).__name__}")
    return shading


def _spec(width, height, device, shading, depth, shadow_samples, options) -> tuple:
    """What names a worker's renderer besides the scene: hashable, picklable."""
    from ..backends.limits import check_size

    width, height = check_size(width, height)
    return (width, height, device, shading, depth, shadow_samples, tuple(sorted(options.items())))


# The scenes this process's jobs scattered, the last KEEP_RENDERERS: (client
# id, key) -> Future. Held here between jobs, because a key released and
# scattered again at once can be dropped by the scheduler under the new job
# (its tasks then fail with "lost dependencies").
_scattered: OrderedDict = OrderedDict()


def _scatter(client, scene: Scene, fresh: bool = False):
    """The scene on every worker, once: the tasks find it there and carry
    only its key. The key is a hash of the scene, so a later job of the same
    scene reuses it, and finds the workers' renderers warm. fresh: a copy
    sent again because the last was lost goes under a key of its own: the
    lost key's release can still be on its way to the scheduler, and would
    take a copy under the same key with it."""
    from dask.base import tokenize

    if not isinstance(scene, Scene):
        raise RaybenchError(f"scene: must be a raybench.Scene, got {type(scene).__name__}")
    held = (id(client), f"Scene-{tokenize(scene)}")
    future = _scattered.get(held)
    if future is None or future.client is not client or future.status != "finished":
        try:
            future = client.scatter(scene, broadcast=True, hash=not fresh)
        except (OSError, TimeoutError) as exc:
            raise RaybenchError(f"cluster: the scene could not be sent to its workers ({one_line(exc)})") from None
        _scattered[held] = future
        while len(_scattered) > KEEP_RENDERERS:
            _scattered.popitem(last=False)[1].release()
    _scattered.move_to_end(held)
    return future, future.key


def _send_again(client, scene: Scene, tried: int, what: str):
    """(future, key) of the scene to send a lost task again with: a worker
    that dies (killed, crashed, out of memory) can take the scene's last copy
    with it, and the scheduler then forgets the tasks that needed it. The
    client waits up to RESTART_WAIT_S for a worker (the nannies restart
    theirs), scatters the scene again, and the task goes again, up to
    LOST_RETRIES times; else one line saying what was lost."""
    from distributed import TimeoutError as DaskTimeout

    if tried >= LOST_RETRIES:
        raise RaybenchError(f"cluster: {what} were lost {tried + 1} times with their workers")
    try:
        client.wait_for_workers(1, timeout=RESTART_WAIT_S)
    except (OSError, DaskTimeout):
        raise RaybenchError(
            f"cluster: its workers were lost, with {what}, and none was back within {RESTART_WAIT_S:g} s"
        ) from None
    return _scatter(client, scene, fresh=True)


def _killed(exc) -> RaybenchError:
    """One line for a task that Dask gave up on: its workers died with it
    (distributed.scheduler.allowed-failures times)."""
    return RaybenchError(f"cluster: a task's workers kept dying under it ({one_line(exc)})")


class _Session:
    """What render() keeps for one client from frame to frame. A frame's fixed
    cost is Dask's round of its tiles (docs/notes/scaling.md), so nothing else asks
    the cluster what a recent frame asked:

    - pool: the frames' shared memory, a frame size's block kept resident;
    - the workers' devices (check_workers), asked again after WORKERS_FRESH_S,
      so that workers that came or went are seen; a tile that lands on a worker
      lacking the device still fails naming it (_tile);
    - last: the last frame's tiles, let go only once the next frame's are
      submitted. Let go at the end of their frame, their release went to the
      scheduler just before the next frame's tiles, which then waited out the
      client's batching interval (10 ms in distributed 2026.8) behind it."""

    def __init__(self, client):
        self.client = weakref.ref(client)
        self.pool = sharedframe.Pool()
        self.found: dict[tuple, tuple[float, dict[str, str]]] = {}
        self.last: list = []

    def workers(self, client, device: str, options: dict) -> dict[str, str]:
        key = (device, options.get("adapter"))
        asked = self.found.get(key)
        if asked is None or time.monotonic() - asked[0] > WORKERS_FRESH_S:
            asked = self.found[key] = (time.monotonic(), check_workers(client, device, **options))
        return asked[1]

    def close(self) -> None:
        self.pool.close()
        self.found.clear()
        self.last = []


# Each client's _Session: id(client) -> _Session, kept from job to job.
_sessions: dict[int, _Session] = {}


def _session(client) -> _Session:
    held = _sessions.get(id(client))
    if held is None or held.client() is not client:
        if held is not None:  # a client of the same id, gone
            held.close()
        held = _sessions[id(client)] = _Session(client)
    return held


def pool(client) -> sharedframe.Pool:
    """The shared memory that render() keeps for client's frames (Pool.made: the blocks it made)."""
    return _session(client).pool


def release(client, workers: bool = True) -> None:
    """The shared memory that render() keeps for client's frames let go, here
    and (workers) on its workers (Cluster.close() does this), with the rest it
    keeps for them. Frames already returned stay valid; a later render() starts afresh."""
    from distributed import TimeoutError as DaskTimeout

    held = _sessions.pop(id(client), None)
    if held is None:
        return
    held.close()
    if workers and held.client() is client and client.status == "running":
        # the workers' mappings keep a block's memory alive: dropped now, not when they next map one
        with contextlib.suppress(OSError, DaskTimeout, RuntimeError):
            client.run(sharedframe.forget)


def tile_rows(height: int, workers: int) -> int:
    """Rows of a tile: about TASKS_PER_WORKER tiles a worker, whole packets of rows."""
    rows = math.ceil(height / max(1, workers * TASKS_PER_WORKER))
    return max(TILE_ALIGN, math.ceil(rows / TILE_ALIGN) * TILE_ALIGN)


def render(
    client,
    scene: Scene,
    camera: Camera | None = None,
    width: int = 800,
    height: int = 600,
    device: str = "cpu",
    shading: str | ShadingOptions = "thesis",
    rows: int | None = None,
    shared: bool = True,
    **options,
) -> Frame:
    """raybench.render() across the cluster's workers: the frame cut in
    bands of `rows` rows (default: tile_rows()), dealt to the workers in
    turn (Dask may move a band to an idle worker) and assembled here, bit
    for bit the frame one process traces on the same device: "cpu" or
    "cuda" (the devices that trace rows). shading: a ShadingOptions, or
    a shading's name alone.

    shared (default): the frame is made in shared memory (raybench.cluster.sharedframe),
    and a worker on this host writes its rows into it, so that they do not
    travel; a worker elsewhere sends them. shared=False: every tile is sent.
    The memory is kept for the client's next frame of this size, and reused
    once the returned frame's arrays are gone: a frame held stays as it is,
    and a caller who holds each frame until the next one is traced uses two
    blocks in turn. release(client) lets it go.

    A tile lost with its workers is traced again (_send_again); where that
    cannot be, one line says so (RaybenchError)."""
    from distributed import as_completed
    from distributed.client import FutureCancelledError
    from distributed.scheduler import KilledWorker

    if camera is not None and not isinstance(camera, Camera):
        raise RaybenchError(f"camera: must be a raybench.Camera or None, got {type(camera).__name__}")
    shading = _shading(shading, options)
    spec = _spec(width, height, device, shading.shading, shading.depth, shading.shadow_samples, options)
    width, height = spec[0], spec[1]
    session = _session(client)
    found = session.workers(client, device, options)
    device = next(iter(found.values()))
    if device not in ("cpu", "cuda"):
        raise RaybenchError(f"device {device}: traces whole frames only; a frame in tiles needs device cpu or cuda")
    spec = (width, height, device, *spec[3:])
    if rows is None:
        rows = tile_rows(height, len(found))
    if isinstance(rows, bool) or not isinstance(rows, int) or rows < TILE_ALIGN or rows % TILE_ALIGN:
        raise RaybenchError(
            f"rows: a tile's rows must be a multiple of {TILE_ALIGN}, at least {TILE_ALIGN}, got {rows!r}"
        )
    camera = camera or scene.camera or Camera()
    # The frame is assembled here, whole: refused before any work if it cannot be
    # (unless a kept block of its size is there to be lent: no new memory).
    if not (shared and session.pool.can_lend(width, height)):
        check_fits("host (where the frame is assembled)", width, height, 0, host_available_bytes(), PIXEL_BYTES)
    future, key = _scatter(client, scene)
    bands = [(a, min(a + rows, height)) for a in range(0, height, rows)]
    lease, ok = None, False
    try:
        lease = session.pool.lease(width, height) if shared else None
        address = None if lease is None else lease.address
        # The tiles dealt to the workers in turn: left to Dask, a frame's few tiles, whose inputs
        # every worker holds, could all go to one GPU (docs/notes/scaling.md). Loosely: a worker that
        # dies or lags has its tiles run, or stolen, by the others.
        places = sorted(found)
        tasks = [
            client.submit(_tile, future, key, spec, camera, band, address, pure=False,
                          workers=[places[i % len(places)]], allow_other_workers=True)
            for i, band in enumerate(bands)
        ]  # fmt: skip
        session.last = []  # the last frame's tiles let go: their release goes out with these
        if lease is None:
            image, hits = np.empty((height, width, 3), np.uint8), np.empty((height, width), np.int32)
        else:
            image, hits = lease.image, lease.hits
        rays, build_s, sent = None, None, False
        try:
            # one tile's result fetched at a time (not with_results=True, which fetches every
            # finished tile's at once: sent rows would then all be held here beside the frame)
            tries = {task: (band, 0) for task, band in zip(tasks, bands, strict=True)}
            pending = as_completed(tasks)
            for task in pending:
                band, tried = tries.pop(task)
                try:
                    first, band_image, band_hits, band_rays, band_build = task.result()
                except FutureCancelledError:  # lost with its workers: sent again (Dask alone cannot)
                    future, key = _send_again(client, scene, tried, f"rows {band[0]} to {band[1]} of the frame")
                    again = client.submit(_tile, future, key, spec, camera, band, address, pure=False)
                    tries[again] = (band, tried + 1)
                    tasks.append(again)
                    pending.add(again)
                    continue
                except KilledWorker as exc:
                    raise _killed(exc) from None
                if band_image is not None:  # sent: a worker that could not write to the block, or none
                    image[first : first + len(band_image)] = band_image
                    hits[first : first + len(band_hits)] = band_hits
                    sent = True
                if band_rays is not None:
                    rays = {k: (rays or {}).get(k, 0) + n for k, n in band_rays.items()}
                build_s = band_build if build_s is None else max(build_s, band_build or 0.0)
            ok = True
            if not sent:  # held till the next frame's tiles go (_Session); sent rows are not held on the workers
                session.last = tasks
        finally:
            if not ok:  # the others are not wanted now (a round trip to the scheduler: not paid when all are done)
                client.cancel(tasks)
                session.found.clear()  # the next frame asks the workers afresh
    finally:
        # Done, failed or interrupted: the block's name goes now, and a task
        # that starts later finds none. Failed or interrupted: a task still
        # running may write into the block, so it is not lent again.
        if lease is not None:
            lease.end(ok)
    return Frame(image=image, hits=hits, device=device, build_s=build_s, rays=rays)


def _runs(items: list, workers: int, per_task: int | None) -> list[list]:
    """items cut into the runs of a sequence's tasks: per_task each, by
    default about TASKS_PER_WORKER a worker and at most MAX_FRAMES_PER_TASK."""
    if per_task is None:
        per_task = min(MAX_FRAMES_PER_TASK, math.ceil(len(items) / (workers * TASKS_PER_WORKER)))
    if isinstance(per_task, bool) or not isinstance(per_task, int) or per_task < 1:
        raise RaybenchError(f"frames_per_task: must be a whole number >= 1, got {per_task!r}")
    return [items[i : i + per_task] for i in range(0, len(items), per_task)]


def trace_frames(
    client,
    scene: Scene,
    cameras: Iterable[Camera],
    width: int = 800,
    height: int = 600,
    device: str = "auto",
    frames_per_task: int | None = None,
    **options,
) -> list[int]:
    """The frames of cameras traced across the workers as render_sequence
    traces them, but kept there: each comes back as the count of its pixels
    that hit a sphere. The throughput of the workers' devices alone, without
    encoding or moving pictures (the bench's multi-gpu suite)."""
    cameras = list(cameras)
    spec = _spec(width, height, device, "thesis", None, None, options)
    found = check_workers(client, device, **options)
    spec = (spec[0], spec[1], next(iter(found.values())), *spec[3:])
    future, key = _scatter(client, scene)
    tasks = [client.submit(_hit_counts, future, key, spec, run, pure=False)
             for run in _runs(cameras, len(found), frames_per_task)]  # fmt: skip
    from distributed.client import FutureCancelledError
    from distributed.scheduler import KilledWorker

    try:
        return [n for counts in client.gather(tasks) for n in counts]
    except FutureCancelledError:  # a measurement: not sent again, which would time the restart too
        raise RaybenchError("cluster: frames were lost with their workers mid-measurement; run it again") from None
    except KilledWorker as exc:
        raise _killed(exc) from None
    finally:
        client.cancel(tasks)


def render_sequence(
    client,
    scene: Scene,
    cameras: Iterable[Camera],
    out_dir,
    width: int = 800,
    height: int = 600,
    device: str = "auto",
    shading: str | ShadingOptions = "thesis",
    sequence_options: SequenceOptions | None = None,
    **options,
) -> list[Path]:
    """One PNG a camera, out_dir/frame_00000.png on, traced across the
    cluster's workers in tasks of frames_per_task frames, encoded there at
    zlib's png_level (default render.PNG_LEVEL) and each written here,
    atomically, as it arrives (frames_per_task, png_level and on_frame: the
    SequenceOptions given, else its defaults; shading: a ShadingOptions, or
    a shading's name alone). A frame already on disk is not traced
    again (an interrupted sequence resumes), once raybench.sequence.prepare
    has found the folder to hold nothing but frames of this sequence (one
    line, before any work, otherwise); on_frame(number, path) is called for
    every frame, skipped ones first. The frames' paths, in order."""
    from distributed import as_completed
    from distributed.client import FutureCancelledError
    from distributed.scheduler import KilledWorker

    from ..files import write_atomic
    from ..render import check_png_level

    shading = _shading(shading, options)
    for misplaced in ("frames_per_task", "on_frame", "png_level"):
        if misplaced in options:
            raise RaybenchError(f"{misplaced}: give it in sequence_options=cluster.SequenceOptions(...)")
    if sequence_options is None:
        sequence_options = SequenceOptions()
    frames_per_task, on_frame = sequence_options.frames_per_task, sequence_options.on_frame
    png_level = sequence_options.png_level
    check_png_level(png_level)
    cameras = list(cameras)
    for i, camera in enumerate(cameras):
        if not isinstance(camera, Camera):
            raise RaybenchError(f"cameras[{i}]: must be a raybench.Camera, got {type(camera).__name__}")
    out_dir = Path(out_dir)
    if not out_dir.is_dir():
        raise RaybenchError(f"{out_dir}: not a folder; make it first")
    spec = _spec(width, height, device, shading.shading, shading.depth, shading.shadow_samples, options)
    marker = sequence.identity(scene, cameras, spec[0], spec[1], shading.shading, shading.depth, shading.shadow_samples)
    missing = set(sequence.prepare(out_dir, marker))
    found = check_workers(client, device, **options)
    spec = (spec[0], spec[1], next(iter(found.values())), *spec[3:])
    paths = [frame_path(out_dir, n) for n in range(len(cameras))]
    todo = []
    for n, path in enumerate(paths):
        if n not in missing:
            if on_frame is not None:
                on_frame(n, path)
        else:
            todo.append((n, cameras[n]))
    if not todo:
        return paths
    runs = _runs(todo, len(found), frames_per_task)
    future, key = _scatter(client, scene)
    tries = {client.submit(_frames, future, key, spec, run, png_level, pure=False): (run, 0) for run in runs}
    submitted = list(tries)
    pending = as_completed(submitted)
    try:
        for task in pending:
            run, tried = tries.pop(task)
            try:
                done = task.result()
            except FutureCancelledError:  # lost with its workers: sent again (Dask alone cannot)
                try:
                    future, key = _send_again(client, scene, tried, f"frames {run[0][0]} to {run[-1][0]}")
                except RaybenchError as exc:
                    raise RaybenchError(f"{exc}; the frames written are kept: run it again to resume") from None
                again = client.submit(_frames, future, key, spec, run, png_level, pure=False)
                tries[again] = (run, tried + 1)
                submitted.append(again)
                pending.add(again)
                continue
            except KilledWorker as exc:
                raise RaybenchError(f"{_killed(exc)}; the frames written are kept: run it again to resume") from None
            for n, png in done:
                write_atomic(paths[n], png)
                if on_frame is not None:
                    on_frame(n, paths[n])
    finally:
        # Ctrl-C or an error: what is written stays; what is queued is dropped.
        client.cancel(submitted)
    return paths
