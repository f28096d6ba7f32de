"""What runs on a worker: the device it resolves, the warm renderers it
keeps, and the tasks that trace with them.

A worker keeps a warm Renderer per (scene, size, device, options): the
scene is scattered once to every worker (broadcast), tasks name it by its
key, and the kernels, the tree and the device's buffers are made on the
first task and reused by the next.
"""

from __future__ import annotations

import threading
from collections import OrderedDict

from ..camera import Camera
from ..errors import RaybenchError, one_line
from ..layout import KINDS
from ..render import Renderer
from ..scene import Scene
from . import sharedframe

# Warm renderers a worker keeps; each holds a frame's buffers and a tree.
KEEP_RENDERERS = 2


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
                # copy out of them (docs/notes/scaling.md)
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
