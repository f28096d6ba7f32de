"""What every backend's Tracer does: the contract that render(), the bench,
the viewer and the tests rely on, written down once.

A Tracer is made for one scene at one size, as Tracer(spheres, width,
height, options=None, shading=None): spheres the scene's (7, N) float32
array, options the device's as backends.options.checked made them (None:
its defaults), shading the Shading of a Whitted frame (None: the thesis's
shading); each takes primitive too (a name of kernels/primitives'
KINDS: its "triangle" traces meshes.mesh_leaves' buffer in place of
spheres, and the cpu's a meshes.Painted mesh too, of which backends.tracer
makes that buffer for the others). It keeps what a frame needs
(the tree, the buffers, the compiled kernel) between frames, and traces a
frame on each call into its host arrays `image` and `hits`, the same ones
frame after frame unless its caller hands it others: a Renderer gives each
frame arrays of their own that way, without a copy (render.Renderer).
"""

from __future__ import annotations

from typing import Protocol, runtime_checkable

import numpy as np

from ..errors import RaybenchError
from .options import checked


@runtime_checkable
class Tracer(Protocol):
    name: str  # the device: "cpu", "cuda" or "wgpu"
    width: int
    height: int
    count: int  # spheres loaded
    # The device's options as backends/options.py checked them (CpuOptions,
    # CudaOptions or WgpuOptions), defaults filled in.
    options: object
    accel: str  # "bvh" or "none"
    walk: str | None  # the BVH walk ("ray" or "packet"), None where the device has one kind or for brute force
    build_s: float | None  # the last BVH build's seconds, apart from any frame; None for brute force
    # The last frame's rays by kind (layout.KINDS), as the kernel
    # counted them; None under the thesis's shading: one primary ray a pixel.
    ray_counts: np.ndarray | None
    # The host arrays the next trace() writes, (H, W, 3) uint8 and (H, W)
    # int32: read at each trace, never kept elsewhere (in converted launch
    # arguments, say), so a caller may replace them between frames with
    # C-contiguous arrays of the same shape and type (host_array's).
    image: np.ndarray
    hits: np.ndarray
    # trace() takes rows=(first, end), tracing only those rows of the frame
    # (the tiles of raybench.cluster): the cpu's and cuda's do.
    traces_rows: bool
    # launch(basis, rows=...), then fetch_into(image_rows, hit_rows) copies
    # those rows from the device straight into the caller's memory, which
    # pin(address, size) page-locks (fetch() into the tracer's own arrays
    # instead): cuda's does, for a cluster's frame in shared memory.
    fetches_into: bool

    def compile(self) -> float:
        """Compile what a frame needs, tracing nothing; the seconds it took."""
        ...

    def trace(self, basis: np.ndarray, count: int | None = None) -> tuple[np.ndarray, np.ndarray]:
        """Trace a frame of the first `count` spheres (default all) seen from
        Camera.basis(); the (H, W, 3) uint8 image and (H, W) int32 hits:
        the arrays self.image and self.hits, which the next frame overwrites
        unless they are replaced first."""
        ...

    def host_array(self, shape: tuple, dtype) -> np.ndarray:
        """A new array for frames (an image or hits to replace self.image or
        self.hits), in the host memory this device writes frames into best."""
        ...

    def timed_trace(self, basis: np.ndarray, count: int | None = None) -> float | None:
        """trace(), returning the device's own kernel time in ms, or None where
        the device has no separate clock (the CPU, numba's simulator)."""
        ...

    def describe(self) -> dict | None:
        """What ran the frames beyond the device's name (wgpu: the adapter), for records."""
        ...

    def update(self, spheres: np.ndarray) -> str | None:
        """The spheres moved (as many as before, a (7, N) float32 array like
        the first): the next frames show them. Their BVH follows, "build"
        (rebuilt) or "refit" (its boxes updated, cuda's GPU-built tree) is
        returned, and build_s is what it took; None for brute force."""
        ...

    def close(self) -> None:
        """Release what the Tracer holds; it traces no more frames."""
        ...


class TracerBase:
    """The part of the contract every backend shares: `with` closes, and by
    default a device has one walk and nothing more to describe."""

    walk: str | None = None
    build_s: float | None = None
    ray_counts: np.ndarray | None = None
    traces_rows: bool = False
    fetches_into: bool = False

    def describe(self) -> dict | None:
        return None

    def _options(self, options, shading):
        """The constructor's options: those given, or for None the device's defaults under this shading."""
        return checked(self.name, {}, shading) if options is None else options

    def host_array(self, shape: tuple, dtype) -> np.ndarray:
        return np.empty(shape, dtype)

    def close(self) -> None:
        pass

    def __enter__(self):
        return self

    def __exit__(self, *exc) -> None:
        self.close()


def check_moved(spheres, like: np.ndarray) -> np.ndarray:
    """Tracer.update's spheres, checked as a scene file's are (scene.check_values:
    no NaN or infinity, radii above 0, colours in [0, 1], centres within
    range), in an array of the shape and type of the tracer's own (like).
    A copy, the tracer's own: the caller's array, changed after the update,
    would otherwise be traced against the tree of what it held before."""
    from ..scene import check_spheres  # here: the scene imports what the backends' package does

    given = np.asarray(spheres)
    if given.shape != like.shape or given.dtype != np.float32:
        raise RaybenchError(
            f"update: spheres must be a {like.shape} float32 array like the tracer's, got {given.shape} {given.dtype}"
        )
    spheres = np.array(given, order="C", copy=True)  # rows as the kernels and the uploads read them
    check_spheres(spheres, "update: ")
    return spheres
