"""raybench's work on Dask workers: one large frame in tiles, or a sequence of
frames, traced across the workers of a Dask cluster and gathered here.

Dask does the distribution (scatter, scheduling, retries when a worker dies);
this module decides only what a worker owns and what a task is:

- A worker owns one device: an embedded cluster starts one worker process
  per GPU, each pinned to its GPU by CUDA_VISIBLE_DEVICES, or with no GPU N
  processes that share the cores (each traces on cores // N threads). Every
  embedded process listens on 127.0.0.1 only, and only over TLS with a key
  made for this cluster and held in memory (Dask's Security.temporary()):
  whoever can reach a Dask port can run code there, so no other process,
  another user's least of all, gets in. A scheduler's address (scheduler=,
  or RAYBENCH_SCHEDULER) joins a cluster started elsewhere, trusted with
  code execution in this process (Dask sends pickles both ways); tls://
  addresses take the CA, certificate and key given, or Dask's config.
- A worker keeps a warm Renderer per (scene, size, device, options): the
  scene is scattered once to every worker (broadcast), tasks name it by its
  key, and the kernels, the tree and the device's buffers are made on the
  first task and reused by the next.
- A task is a band of rows of one frame (a tile: bit for bit the rows of the
  whole frame's render, on cpu and cuda) or a run of whole frames of a sequence (their PNGs,
  encoded on the worker).
- A tile's rows do not travel where they need not: the client makes the frame
  in shared memory (raybench.cluster.sharedframe) and a worker on its host writes its
  rows there; a worker on another host sends them through Dask. The client
  keeps that memory from frame to frame of one size (a sharedframe.Pool per
  client, let go by release(client) or Cluster.close()), with its pages
  resident, and the workers keep their mappings of it.

Why the embedded workers differ from Dask's defaults (docs/scaling.md has
the measurements): a Nanny's worker gets MALLOC_TRIM_THRESHOLD_=65536 in its
environment, which makes glibc map and fault in afresh every frame-sized
allocation (several times slower copies of a frame); and a Nanny's default
thread count is every core, which runs several tasks at once on one device.
raybench's workers take one task at a time, without that variable.
"""

from __future__ import annotations

import contextlib
import logging
import math
import os
import threading
import time
import weakref
from collections import OrderedDict
from collections.abc import Callable, Iterable
from pathlib import Path

import numpy as np

from .. import sequence
from ..backends.limits import PIXEL_BYTES, check_connect_timeout, check_fits, check_worker_count
from ..camera import Camera
from ..errors import RaybenchError, one_line
from ..host import host_available_bytes, usable_cores
from ..kernels.whitted import KINDS
from ..render import PNG_LEVEL, Frame, Renderer
from ..scene import Scene
from ..sequence import frame_path
from . import sharedframe

HOST = "127.0.0.1"  # every process of an embedded cluster listens here only
SCHEDULER_ENV = "RAYBENCH_SCHEDULER"
# How long to try a scheduler's address before saying it is unreachable.
CONNECT_TIMEOUT_S = 10.0
# The BVH's packets are 8 rows high (backends.cpu.PACKET_H): a tile starts on one.
TILE_ALIGN = 8
# Tasks a worker gets of one job, by default: enough that a slow or lost
# worker's share is made up by the others, few enough that the scheduler's
# cost per task (docs/scaling.md) stays small beside the tracing.
TASKS_PER_WORKER = 4
# The most frames a task of a sequence traces, so progress is seen often.
MAX_FRAMES_PER_TASK = 60
# Warm renderers a worker keeps; each holds a frame's buffers and a tree.
KEEP_RENDERERS = 2
# How often a task (a tile, a run of frames) is sent again when the workers it was on are lost
# with it, and how long the client waits, each time, for a worker to trace it (a nanny restarts a
# killed worker, in a few seconds on the machines measured).
LOST_RETRIES = 3
RESTART_WAIT_S = 60.0
# What an embedded cluster's Dask logs to the terminal (the nannies set it in this process too):
# critical failures only. What it logs as errors (a lost worker's scattered scene, the tasks
# forgotten with it; a restarted worker's warnings) raybench handles, or says in one line.
DASK_LOGS = logging.CRITICAL
# How long render() trusts its last answer of which workers there are and
# what device each has (about the interval at which a Dask client refreshes
# its own view of the scheduler).
WORKERS_FRESH_S = 2.0


# --- the cluster -------------------------------------------------------------------


def gpu_count() -> int:
    """NVIDIA GPUs this process can use (0 under numba's simulator)."""
    from .. import backends

    if not backends.cuda_available():
        return 0
    from numba import cuda

    return len(cuda.gpus)


def worker_specs(device: str, workers: int, security=None) -> dict:
    """The SpecCluster worker specs of an embedded cluster: `workers` Nanny
    processes on 127.0.0.1, one task at a time each; on cuda each pinned to
    one GPU, on the cpu each given its share of the cores. security (a
    distributed Security): their connections' (tls:// where it holds keys)."""
    from distributed import Nanny

    try:
        import psutil

        memory = psutil.virtual_memory().total // workers
    except ImportError:  # psutil is a dependency; without it Dask picks
        memory = "auto"
    specs = {}
    # the GPUs this process may use, in its own numbering: a worker pins one of them
    visible = [g.strip() for g in os.environ.get("CUDA_VISIBLE_DEVICES", "").split(",") if g.strip()]
    for i in range(workers):
        if device == "cuda":
            env = {"CUDA_VISIBLE_DEVICES": visible[i] if i < len(visible) else str(i)}
        else:
            env = {"NUMBA_NUM_THREADS": str(max(1, usable_cores() // workers))}
        for key in ("RAYBENCH_CACHE_DIR", "NUMBA_ENABLE_CUDASIM"):  # the compiled kernels' cache, and the simulator
            if key in os.environ:
                env[key] = os.environ[key]
        specs[f"{device}-{i}"] = {
            "cls": Nanny,
            "options": {
                "nthreads": 1,
                "host": HOST,
                "protocol": _protocol(security),
                "security": security,
                "dashboard_address": f"{HOST}:0",  # Dask's HTTP server (health, metrics) is always started
                "env": env,
                "preload": [__name__],  # dask_setup: Ctrl-C is the client's to handle
                "memory_limit": memory,
                "silence_logs": DASK_LOGS,
            },
        }
    return specs


def _protocol(security) -> str:
    return "tls" if security is not None and security.require_encryption else "tcp"


def embedded_security():
    """The credentials of a new embedded cluster: a self-signed key and
    certificate made now, in memory, that every process of the cluster and
    its client present to each other (mutual TLS): a process without them is
    refused. Dask passes them to the workers it starts through their
    nannies' pipes; they are on no disk but for the moment each process
    loads them (distributed.security, a private temporary folder)."""
    from distributed.security import Security

    return Security.temporary()


def dask_setup(worker) -> None:
    """Dask's hook as each embedded worker starts (worker_specs preloads this
    module there): Ctrl-C at a terminal reaches the whole process group, and
    each worker printed its own KeyboardInterrupt's tracebacks; the client
    handles it and ends the cluster, workers included, so they ignore it."""
    import signal

    if threading.current_thread() is threading.main_thread():
        signal.signal(signal.SIGINT, signal.SIG_IGN)


def default_workers(device: str) -> int:
    return max(1, gpu_count()) if device == "cuda" else 1


class Cluster:
    """A Dask client and, unless it joined one by address, the embedded
    cluster it talks to; a `with` block closes both (the embedded workers'
    processes end with it).

        with raybench.cluster.Cluster(workers=2, device="cpu") as cluster:
            frame = raybench.cluster.render(cluster.client, scene, width=1680, height=1050, device="cpu")

    device picks the embedded workers' kind ("auto": one per GPU where
    there is one, else the CPU); scheduler (default: RAYBENCH_SCHEDULER)
    joins an existing cluster, tried for timeout seconds. security (a
    distributed.security.Security): an embedded cluster's connections, by
    default TLS with credentials made for it alone (embedded_security();
    Security() gives plain TCP, which any local process can join); a joined
    one's, by default Dask's config (distributed.comm.tls)."""

    def __init__(
        self,
        workers: int | None = None,
        device: str = "auto",
        scheduler: str | None = None,
        timeout: float = CONNECT_TIMEOUT_S,
        security=None,
    ):
        import dask
        from distributed import Client, Scheduler, SpecCluster

        from .. import backends

        scheduler = scheduler or os.environ.get(SCHEDULER_ENV) or None
        timeout = check_connect_timeout(timeout)
        self.cluster = None
        if scheduler is not None:
            if workers is not None:
                raise RaybenchError("workers: a joined cluster has its own; give workers or a scheduler, not both")
            self.client = connect(scheduler, timeout, security)
            return
        device = backends.resolve(device)
        if device == "wgpu":
            raise RaybenchError("device wgpu: the cluster runs cpu or cuda workers")
        if workers is None:
            workers = default_workers(device)
        workers = check_worker_count(workers)
        if device == "cuda" and not backends.module("cuda").simulated() and workers > gpu_count():
            raise RaybenchError(f"workers: {workers} cuda workers need {workers} GPUs; this machine has {gpu_count()}")
        # Dask's default sets MALLOC_TRIM_THRESHOLD_ in a worker's environment;
        # raybench's workers go without it (the module's docstring says why).
        environ = dict(dask.config.get("distributed.nanny.pre-spawn-environ"))
        environ.pop("MALLOC_TRIM_THRESHOLD_", None)
        if security is None:
            security = embedded_security()
        scheduler_options = {"host": HOST, "port": 0, "dashboard_address": f"{HOST}:0",
                             "protocol": _protocol(security), "security": security}  # fmt: skip
        with dask.config.set({"distributed.nanny.pre-spawn-environ": environ}):
            self.cluster = SpecCluster(
                scheduler={"cls": Scheduler, "options": scheduler_options},
                workers=worker_specs(device, workers, security),
                security=security,
                silence_logs=DASK_LOGS,
            )
        try:
            self.client = Client(self.cluster)
        except BaseException:
            self.cluster.close()
            raise

    @property
    def workers(self) -> int:
        return len(self.client.scheduler_info(n_workers=-1)["workers"])

    def close(self) -> None:
        # an embedded cluster's workers end with it, their mappings too: asked only when joined
        release(self.client, workers=self.cluster is None)
        self.client.close()
        if self.cluster is not None:
            self.cluster.close()
            self.cluster = None

    def __enter__(self) -> Cluster:
        return self

    def __exit__(self, *exc) -> None:
        self.close()


def connect(address: str, timeout: float = CONNECT_TIMEOUT_S, security=None):
    """A Client of the scheduler at address, or one line saying it was not
    reached within timeout seconds. security: a distributed Security (for
    tls:// addresses), by default Dask's config."""
    from distributed import Client
    from distributed.security import Security

    timeout = check_connect_timeout(timeout)
    if security is None:
        security = Security()  # Dask's config (distributed.comm.tls), as Client would read it
    if address.startswith("tls://") and not (security.tls_ca_file and security.tls_client_cert):
        raise RaybenchError(
            f"scheduler {address}: a tls:// address needs this client's TLS credentials: give --tls-ca, "
            "--tls-cert and --tls-key (Cluster(security=...)), or set Dask's distributed.comm.tls config"
        )
    try:
        return Client(address, timeout=timeout, security=security)
    except (OSError, TimeoutError, ValueError) as exc:
        reason = " ".join(str(exc).split()) or type(exc).__name__
        raise RaybenchError(f"scheduler {address}: unreachable within {timeout:g} s ({reason})") from None


def check_workers(client, device: str, **options) -> dict[str, str]:
    """Each worker's device for `device`, asked on the worker itself ("auto"
    resolves there); a worker that lacks it is an error that names it."""
    from distributed import TimeoutError as DaskTimeout

    try:
        answers = client.run(_worker_device, device, options.get("adapter"), on_error="return")
    except (OSError, DaskTimeout) as exc:
        raise RaybenchError(f"cluster: its workers did not answer ({one_line(exc)})") from None
    if not answers:
        raise RaybenchError("cluster: it has no workers")
    for worker, answer in sorted(answers.items()):
        if isinstance(answer, BaseException):
            raise RaybenchError(f"worker {worker}: {one_line(answer)}")
    kinds = set(answers.values())
    if len(kinds) > 1:
        raise RaybenchError(f"cluster: its workers resolve device {device!r} to different devices: {sorted(kinds)}")
    return answers


def _worker_device(device: str, adapter: str | None) -> str:
    from .. import backends

    return backends.resolve(device, adapter)


# --- what a worker keeps -------------------------------------------------------------

_renderers: OrderedDict = OrderedDict()
# One task at a time touches a worker's renderers: a worker started with
# several threads (a cluster joined by address) would otherwise trace two
# tasks into one renderer's buffers at once.
task_lock = threading.Lock()


def _renderer(scene: Scene, scene_key: str, spec: tuple) -> Renderer:
    """The worker's warm Renderer of this scene and spec, made on first use."""
    key = (scene_key, spec)
    renderer = _renderers.get(key)
    if renderer is None:
        width, height, device, shading, depth, shadow_samples, options = spec
        options = dict(options)
        if device == "cpu" and "threads" not in options:
            import numba

            options["threads"] = numba.config.NUMBA_NUM_THREADS  # the worker's share of the cores
        renderer = Renderer(scene, width, height, device, shading, depth, shadow_samples, **options)
        _renderers[key] = renderer
        while len(_renderers) > KEEP_RENDERERS:
            _renderers.popitem(last=False)[1].close()
    _renderers.move_to_end(key)
    return renderer


def _tile(
    scene: Scene, scene_key: str, spec: tuple, camera: Camera, rows: tuple[int, int], shared: tuple | None = None
):
    """A task: rows first..end of the frame; (first, image rows, hit rows,
    rays by kind or None, BVH build seconds or None). With shared (the
    address of the client's sharedframe.Lease) the rows are written into it,
    on cuda straight from the GPU, elsewhere once from the tracer's own
    buffers, and come back as None; where this worker cannot open it (another
    host) they come back as before."""
    with task_lock:
        try:
            renderer = _renderer(scene, scene_key, spec)
        except RaybenchError as exc:  # a worker that joined after check_workers, say
            from distributed import get_worker

            raise RaybenchError(f"worker {get_worker().address}: {exc}") from None
        if shared is not None:
            tracer = renderer.tracer
            basis = camera.basis(renderer.width, renderer.height)
            first, end = rows
            if tracer.fetches_into:
                # cuda: the rows copied from the GPU straight into the frame, its
                # mapping page-locked once, not through the tracer's buffers and a
                # copy out of them (docs/scaling.md)
                tracer.launch(basis, rows=rows)
                if sharedframe.fill_rows(shared, first, end - first, tracer.fetch_into, pin=tracer.pin):
                    return first, None, None, _ray_counts(tracer), tracer.build_s
                image, hits = tracer.fetch()
            else:
                image, hits = tracer.trace(basis, rows=rows)
                if sharedframe.write_rows(shared, first, image[first:end], hits[first:end]):
                    return first, None, None, _ray_counts(tracer), tracer.build_s
            # traced already: the rows travel from the tracer's buffers
            return first, image[first:end].copy(), hits[first:end].copy(), _ray_counts(tracer), tracer.build_s
        frame = renderer.render(camera, rows=rows)
    return rows[0], frame.image, frame.hits, frame.rays, frame.build_s


def _ray_counts(tracer) -> dict | None:
    """The last trace's rays by kind, as Frame.rays has them."""
    counts = tracer.ray_counts
    return None if counts is None else dict(zip(KINDS, counts.tolist()))


def _hit_counts(scene: Scene, scene_key: str, spec: tuple, cameras: list[Camera]) -> list[int]:
    """A task: whole frames traced in the renderer's own buffers, each
    reduced to the count of its pixels that hit a sphere."""
    width, height = spec[0], spec[1]
    with task_lock:
        renderer = _renderer(scene, scene_key, spec)
        return [int((renderer.tracer.trace(c.basis(width, height))[1] >= 0).sum()) for c in cameras]


def _frames(scene: Scene, scene_key: str, spec: tuple, numbered: list[tuple[int, Camera]], level: int):
    """A task: whole frames of a sequence; [(number, PNG bytes at zlib's level)]."""
    with task_lock:
        renderer = _renderer(scene, scene_key, spec)
        return [(n, renderer.render(camera, hits=False).png_bytes(level)) for n, camera in numbered]


# --- jobs -----------------------------------------------------------------------------


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
    cost is Dask's round of its tiles (docs/scaling.md), so nothing else asks
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
    shading: str = "thesis",
    depth: int | None = None,
    shadow_samples: int | None = None,
    rows: int | None = None,
    shared: bool = True,
    **options,
) -> Frame:
    """raybench.render() across the cluster's workers: the frame cut in
    bands of `rows` rows (default: tile_rows()), dealt to the workers in
    turn (Dask may move a band to an idle worker) and assembled here, bit
    for bit the frame one process traces on the same device: "cpu" or
    "cuda" (the devices that trace rows).

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
    spec = _spec(width, height, device, shading, depth, shadow_samples, options)
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
        # every worker holds, could all go to one GPU (docs/scaling.md). Loosely: a worker that
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
    shading: str = "thesis",
    depth: int | None = None,
    shadow_samples: int | None = None,
    frames_per_task: int | None = None,
    on_frame: Callable[[int, Path], None] | None = None,
    png_level: int = PNG_LEVEL,
    **options,
) -> list[Path]:
    """One PNG a camera, out_dir/frame_00000.png on, traced across the
    cluster's workers in tasks of frames_per_task frames, encoded there at
    zlib's png_level (default render.PNG_LEVEL) and each written here,
    atomically, as it arrives. A frame already on disk is not traced
    again (an interrupted sequence resumes), once raybench.sequence.prepare
    has found the folder to hold nothing but frames of this sequence (one
    line, before any work, otherwise); on_frame(number, path) is called for
    every frame, skipped ones first. The frames' paths, in order."""
    from distributed import as_completed
    from distributed.client import FutureCancelledError
    from distributed.scheduler import KilledWorker

    from ..files import write_atomic
    from ..render import check_png_level

    check_png_level(png_level)
    cameras = list(cameras)
    for i, camera in enumerate(cameras):
        if not isinstance(camera, Camera):
            raise RaybenchError(f"cameras[{i}]: must be a raybench.Camera, got {type(camera).__name__}")
    out_dir = Path(out_dir)
    if not out_dir.is_dir():
        raise RaybenchError(f"{out_dir}: not a folder; make it first")
    spec = _spec(width, height, device, shading, depth, shadow_samples, options)
    marker = sequence.identity(scene, cameras, spec[0], spec[1], shading, depth, shadow_samples)
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
