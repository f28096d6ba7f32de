"""render(): scene and camera in, a Frame out, on the chosen device."""

from __future__ import annotations

import io
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from . import backends
from .backends.limits import check_size
from .camera import Camera
from .errors import RaybenchError
from .files import write_atomic
from .scene import Scene


@dataclass
class Frame:
    """A traced picture: image is (H, W, 3) uint8 RGB, row 0 at the top; hits
    holds the index of the sphere seen in each pixel, -1 where the ray missed."""

    image: np.ndarray
    hits: np.ndarray
    device: str
    build_s: float | None = None  # the BVH's build, apart from the trace; None for brute force

    @property
    def width(self) -> int:
        return self.image.shape[1]

    @property
    def height(self) -> int:
        return self.image.shape[0]

    def png_bytes(self) -> bytes:
        return png_bytes(self.image)

    def _repr_png_(self) -> bytes:
        return self.png_bytes()

    def save(self, path) -> None:
        """Write the image as PNG, atomically."""
        path = Path(path)
        if path.suffix.lower() != ".png":
            raise RaybenchError(f"{path}: the output must be a .png file")
        write_atomic(path, self.png_bytes())


def png_bytes(image: np.ndarray) -> bytes:
    """An (H, W, 3) uint8 RGB image as PNG file contents: the one encoder every
    sink that writes pictures uses (Frame.save, the viewer's screenshots)."""
    from PIL import Image

    buf = io.BytesIO()
    Image.fromarray(image, "RGB").save(buf, format="PNG")
    return buf.getvalue()


def render(
    scene: Scene, camera: Camera | None = None, width: int = 800, height: int = 600, device: str = "auto", **options
) -> Frame:
    """Trace one frame of scene as seen by camera (default: the scene's own
    camera, else Camera()). device is "cpu", "cuda", "wgpu" or "auto"; options go
    to the device (cpu: threads=N; cuda: block=(x, y); wgpu: workgroup=(x, y),
    adapter="name", needed for a CPU driver such as llvmpipe; every device:
    accel="bvh" (the default) or "none", brute force with kernel="fast" or
    "simple" on cpu and cuda, "simple" only on wgpu)."""
    if not isinstance(scene, Scene):
        raise RaybenchError(f"scene: must be a raybench.Scene, got {type(scene).__name__}")
    if camera is not None and not isinstance(camera, Camera):
        raise RaybenchError(f"camera: must be a raybench.Camera or None, got {type(camera).__name__}")
    width, height = check_size(width, height)
    camera = camera or scene.camera or Camera()
    tracer = backends.tracer(device, scene.spheres, width, height, **options)
    try:
        image, hits = tracer.trace(camera.basis(width, height))
        return Frame(image=image.copy(), hits=hits.copy(), device=tracer.name, build_s=getattr(tracer, "build_s", None))
    finally:
        tracer.close()
