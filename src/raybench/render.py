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
from .kernels.whitted import KINDS
from .lighting import Shading, check_shading
from .scene import Scene


@dataclass
class Frame:
    """A traced picture: image is (H, W, 3) uint8 RGB, row 0 at the top; hits
    holds the index of the sphere seen in each pixel, -1 where the ray missed."""

    image: np.ndarray
    hits: np.ndarray
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
    camera, else Camera()). device is "cpu", "cuda", "wgpu" or "auto".
    shading: "thesis" (the default: each sphere's colour darkened towards its
    rim) or "whitted" (the scene's lights with shadows, mirrors and glass, to
    `depth` bounces, default 5; an area light's soft shadow from
    `shadow_samples` rays, default 4). options go to the device (cpu:
    threads=N; cuda: block=(x, y); wgpu: workgroup=(x, y), adapter="name",
    needed for a CPU driver such as llvmpipe; every device: accel="bvh" (the
    default) or "none", brute force with kernel="fast" or "simple" on cpu and
    cuda, "simple" only on wgpu and under Whitted shading)."""
    if not isinstance(scene, Scene):
        raise RaybenchError(f"scene: must be a raybench.Scene, got {type(scene).__name__}")
    check_size(width, height)
    camera = camera or scene.camera or Camera()
    if check_shading(shading) == "whitted":
        options["whitted"] = Shading.of(scene, depth, shadow_samples)
    elif depth is not None or shadow_samples is not None:
        raise RaybenchError("depth and shadow_samples: apply to shading='whitted' only")
    with backends.tracer(device, scene.spheres, width, height, **options) as tracer:
        image, hits = tracer.trace(camera.basis(width, height))
        rays = None if tracer.ray_counts is None else dict(zip(KINDS, tracer.ray_counts.tolist()))
        return Frame(image=image.copy(), hits=hits.copy(), device=tracer.name, build_s=tracer.build_s, rays=rays)
