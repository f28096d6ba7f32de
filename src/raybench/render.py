"""render(): scene and camera in, a Frame out, on the chosen device."""

from __future__ import annotations

import io
import sys
import threading
import weakref
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from . import backends
from .backends.limits import check_size
from .camera import Camera
from .errors import RaybenchError
from .files import write_atomic
from .layout import KINDS
from .lighting import Shading, check_shading
from .scene import Scene

# zlib's level for every PNG raybench writes, a frame or a sequence's: level 1
# encodes faster than Pillow's default 6, in files a little larger for a smooth
# picture and smaller for a busy one. At 6 the encoding was most of a warm
# `raybench render` and bounded a sequence (the figures:
# docs/notes/startup.md#figures-moved-from-the-sources-comments,
# docs/notes/scaling.md#the-png-sequence-is-bound-by-encoding).
PNG_LEVEL = 1


@dataclass
class Frame:
    """A traced picture: image is (H, W, 3) uint8 RGB, row 0 at the top; hits
    holds the index of the sphere seen in each pixel, -1 where the ray missed.
    Its arrays are its own: no later frame writes into them."""

    image: np.ndarray
    hits: np.ndarray | None  # None where the caller asked for none (Renderer.render(hits=False))
    device: str
    build_s: float | None = None  # the BVH's build, apart from the trace; None for brute force
    # Whitted shading: the rays the kernel cast, by kind (primary, shadow,
    # reflection, refraction); None under the thesis's (one ray a pixel).
    rays: dict | None = None

    @property
    def width(self) -> int:
        return self.image.shape[1]

    @property
    def height(self) -> int:
        return self.image.shape[0]

    def png_bytes(self, level: int = PNG_LEVEL) -> bytes:
        return png_bytes(self.image, level)

    def _repr_png_(self) -> bytes:
        return self.png_bytes()

    def save(self, path, level: int = PNG_LEVEL) -> None:
        """Write the image as PNG, atomically; level is zlib's (png_bytes)."""
        path = Path(path)
        if path.suffix.lower() != ".png":
            raise RaybenchError(f"{path}: the output must be a .png file")
        write_atomic(path, self.png_bytes(check_png_level(level)))


def check_png_level(level) -> int:
    if isinstance(level, bool) or not isinstance(level, int) or not 0 <= level <= 9:
        raise RaybenchError(f"PNG level: must be a whole number 0 (no compression) to 9 (smallest), got {level!r}")
    return level


def png_bytes(image: np.ndarray, level: int = PNG_LEVEL) -> bytes:
    """An (H, W, 3) uint8 RGB image as PNG file contents: the one encoder every
    sink that writes pictures uses (Frame.save, the viewer's screenshots, a
    sequence's frames). level: zlib's, 0 (stored) to 9; 1 encodes faster
    than 6, in files a little larger
    (docs/notes/scaling.md#the-png-sequence-is-bound-by-encoding)."""
    from PIL import Image

    buf = io.BytesIO()
    Image.fromarray(image, "RGB").save(buf, format="PNG", compress_level=check_png_level(level))
    return buf.getvalue()


# The arrays of each kind (images, hits) a Renderer traces frames into and
# lends to them: enough for a frame held while the next is traced and one
# more in flight (the viewer's). A caller who drops its frames in turn traces
# into these few; one who keeps more gets copies, as a fresh array faulted in
# by the kernel's threads costs more than a copy into it
# (docs/notes/startup.md#what-a-renderer-costs-over-its-tracer-2-vcpu-machine).
KEEP_LENT = 3


def _refs(arrays: list, i: int) -> int:
    return sys.getrefcount(arrays[i])


# _refs of an array that nothing but the list holds, counted as _free counts.
_ALONE = _refs([np.empty(0)], 0)


def _free(arrays: list, i: int) -> bool:
    """Whether nothing but the list holds arrays[i]: no Frame, no view of it
    (a NumPy view holds the array that owns its memory: np.empty's, or
    cuda.pinned_array's, whose own base is not an array), no weak reference
    that could bring one back. A frame's arrays are the owners themselves."""
    return _refs(arrays, i) <= _ALONE and not weakref.getweakrefcount(arrays[i])


class _Lent:
    """The arrays of one kind (a frame's images, or its hits) that a
    Renderer's tracer writes frames into and lends to the Frames, each traced
    into again once nothing else holds it: no Frame or view a caller keeps is
    ever written."""

    def __init__(self):
        self._arrays: list[np.ndarray] = []  # at most KEEP_LENT, each a Frame's or free

    def take(self, tracer, like: np.ndarray) -> np.ndarray | None:
        """An array that nothing else holds now; a new one like `like` from
        the tracer (in the memory it writes frames into best) while there are
        fewer than KEEP_LENT; else None: callers hold them all."""
        for i in range(len(self._arrays)):
            if _free(self._arrays, i):
                return self._arrays[i]
        if len(self._arrays) < KEEP_LENT:
            self._arrays.append(tracer.host_array(like.shape, like.dtype))
            return self._arrays[-1]
        return None


class Renderer:
    """A scene kept ready on a device, frame after frame: its tree, the
    device's buffers and the compiled kernel are made once, here, and each
    render(camera) traces one frame. Close it with close() or a `with` block:

        with raybench.Renderer(scene, 1680, 1050, device="cuda", shading="whitted") as renderer:
            for camera in path:
                renderer.render(camera).save(...)

    scene: spheres, meshes (format version 3, or a mesh file by
    mesh_render.mesh_scene), whose triangles are traced, or both (one tree
    of both kinds, kernels/primitives/mixed.py: on every device).
    device, shading, depth, shadow_samples and the device's options are
    render()'s (below); shading may also be a lighting.Shading made ahead
    (Shading.of(scene, ...)), which is Whitted shading with its arrays. For
    spheres that move, update(spheres) moves them between frames.

    One Renderer may be shared by threads: its calls take turns (a lock), so
    each frame is its own camera's. They do not run at once: the device's
    buffers are one frame's. A thread that wants frames in parallel makes a
    Renderer of its own."""

    def __init__(
        self,
        scene: Scene,
        width: int = 800,
        height: int = 600,
        device: str = "auto",
        shading: str | Shading = "thesis",
        depth: int | None = None,
        shadow_samples: int | None = None,
        **options,
    ):
        if not isinstance(scene, Scene):
            raise RaybenchError(f"scene: must be a raybench.Scene, got {type(scene).__name__}")
        width, height = check_size(width, height)
        # one kind of primitive a tracer: the spheres, a mesh scene's triangles, or both (mixed)
        traced = scene.traced()
        if isinstance(shading, Shading):
            if depth is not None or shadow_samples is not None:
                raise RaybenchError("depth and shadow_samples: a Shading holds its own; give one or the other")
            options["shading"], shading = shading, "whitted"
        elif check_shading(shading) == "whitted":
            options["shading"] = Shading.of(traced, depth, shadow_samples)
        elif depth is not None or shadow_samples is not None:
            raise RaybenchError("depth and shadow_samples: apply to shading='whitted' only")
        self.scene, self.width, self.height, self.shading = scene, width, height, shading
        self.tracer = backends.tracer(device, traced.leaves, width, height, primitive=traced.kind, **options)
        self._images, self._hits = _Lent(), _Lent()
        # The tracer's arrays, its camera and its lent arrays are one frame's: one call at a time.
        self._turn = threading.RLock()

    @property
    def device(self) -> str:
        return self._open().name

    def compile(self) -> float:
        """Compile the kernel (or load it from the cache) and build what the
        first frame needs, ahead of it; the seconds that took. render() does
        it by itself when it has not been done."""
        with self._turn:
            return self._open().compile()

    def update(self, spheres: np.ndarray) -> str | None:
        """Move the spheres (a (7, N) float32 array of the scene's N spheres,
        as Scene.spheres) for the next frames: "refit" where the tree's boxes
        were refitted on the GPU (cuda, build="gpu"), "build" where the tree
        was rebuilt, None for brute force. They are checked as a scene file's
        spheres are (one line naming the first that is not a sphere), and
        copied: the caller may change its array afterwards."""
        with self._turn:
            return self._open().update(spheres)

    def render(
        self,
        camera: Camera | None = None,
        hits: bool = True,
        rows: tuple[int, int] | None = None,
        count: int | None = None,
    ) -> Frame:
        """One frame as seen by camera (default: the scene's own camera, else
        Camera()); a Frame of its own arrays, which no later frame writes:
        those the tracer wrote, not copies, unless the caller still holds
        KEEP_LENT earlier frames. hits=False leaves Frame.hits None.
        rows=(first, end): only those rows of the frame (copied out of the
        tracer's), each pixel as the whole frame has it (a tile of
        raybench.cluster's render; first a multiple of 8 on the cpu), on
        devices that trace rows (cpu and cuda). count: only the scene's first
        count spheres (the thesis's test 7 ramps it), or a mesh scene's first
        count triangles, without a new tree or upload where the device allows."""
        with self._turn:
            return self._render(camera, hits, rows, count)

    def _render(self, camera, hits, rows, count) -> Frame:
        tracer = self._open()
        _check_camera(camera)
        camera = camera or self.scene.camera or Camera()
        basis = camera.basis(self.width, self.height)
        if rows is not None and not tracer.traces_rows:
            raise RaybenchError(f"rows: device {tracer.name} traces whole frames only; tiles need device cpu or cuda")
        # The frame is traced into arrays that nothing else holds, handed to
        # the tracer for this trace: a whole frame's become the Frame's, not
        # copied (12 MB a frame at 1680x1050). Where callers hold every lent
        # array, and for a tile's rows (a view would keep a whole frame's
        # arrays alive with each tile), the frame is copied out of the
        # tracer's own arrays, which it keeps for callers of tracer.trace().
        own = tracer.image, tracer.hits
        whole = rows is None
        into = (
            self._images.take(tracer, own[0]) if whole else None,
            self._hits.take(tracer, own[1]) if whole and hits else None,
        )
        tracer.image = own[0] if into[0] is None else into[0]
        tracer.hits = own[1] if into[1] is None else into[1]
        try:
            if whole:
                image, hit_ids = tracer.trace(basis, count)
            else:
                image, hit_ids = tracer.trace(basis, count, rows=rows)
                image, hit_ids = image[rows[0] : rows[1]], hit_ids[rows[0] : rows[1]]
        finally:
            tracer.image, tracer.hits = own
        image = image.copy() if into[0] is None else image
        hit_ids = None if not hits else hit_ids.copy() if into[1] is None else hit_ids
        counts = tracer.ray_counts
        return Frame(
            image=image,
            hits=hit_ids,
            device=tracer.name,
            build_s=tracer.build_s,
            rays=None if counts is None else dict(zip(KINDS, counts.tolist())),
        )

    def _open(self):
        if self.tracer is None:
            raise RaybenchError("renderer: it is closed; make a new Renderer")
        return self.tracer

    def close(self) -> None:
        with self._turn:
            if self.tracer is not None:
                self.tracer.close()
                self.tracer = None
                self._images, self._hits = _Lent(), _Lent()  # the free arrays go (cuda's are page-locked)

    def __enter__(self) -> Renderer:
        return self

    def __exit__(self, *exc) -> None:
        self.close()


def render(
    scene: Scene,
    camera: Camera | None = None,
    width: int = 800,
    height: int = 600,
    device: str = "auto",
    shading: str = "thesis",
    depth: int | None = None,
    shadow_samples: int | None = None,
    **options,
) -> Frame:
    """Trace one frame of scene as seen by camera (default: the scene's own
    camera, else Camera()): a Renderer for one frame. device is "cpu",
    "cuda", "wgpu" or "auto". shading: "thesis" (the default: each sphere's
    colour darkened towards its rim) or "whitted" (the scene's lights with
    shadows, mirrors and glass, to `depth` bounces, default 5; an area light's
    soft shadow from `shadow_samples` rays, default 4). options go to the
    device (cpu: threads=N; cuda: block=(x, y); wgpu: workgroup=(x, y),
    adapter="name", needed for a CPU driver such as llvmpipe; every device:
    accel="bvh" (the default) or "none", brute force with kernel="fast" or
    "simple" on cpu and cuda, "simple" only on wgpu and under Whitted
    shading)."""
    _check_camera(camera)  # before any work
    from .bvh import oneshot  # here: `import raybench` does not import Numba

    # one frame: a small scene's tree may be built uncompiled while the builder compiles (bvh.one_shot)
    with oneshot.one_shot(), Renderer(scene, width, height, device, shading, depth, shadow_samples, **options) as r:
        return r.render(camera)


def _check_camera(camera) -> None:
    if camera is not None and not isinstance(camera, Camera):
        raise RaybenchError(f"camera: must be a raybench.Camera or None, got {type(camera).__name__}")
