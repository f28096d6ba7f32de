"""The CUDA Tracer: its kernels' launches (backends/cuda/program.py has the
kernels) and their buffers."""

from __future__ import annotations

import dataclasses
import math
import time
import warnings

import numpy as np
from numba import cuda
from numba.cuda.core.errors import NumbaPerformanceWarning

from ... import bvh as bvh_mod
from ...errors import RaybenchError
from ...host import host_available_bytes
from ...kernels.primitives import sphere
from ...layout import KINDS, NODE_FLOATS
from ...lighting import Shading
from ..contract import TracerBase, check_moved
from ..limits import (
    HOST_PIXEL_BYTES,
    PIXEL_BYTES,
    check_bvh_fits,
    check_count,
    check_fits,
    check_rows,
)
from ..options import DEFAULT_BLOCK, CudaOptions
from . import build as cuda_build
from .device import require, simulated
from .kinds import programs
from .launch import Launches
from .program import _zero_rays, choose_walk, in_tree_order
from .tree_order import in_tree_order as put_in_tree_order
from .wavefront import Wavefront, row_bytes


class Tracer(TracerBase):
    """Keeps the spheres and the frame buffers on the GPU between frames
    (the contract: backends.contract.Tracer)."""

    name = "cuda"
    traces_rows = True
    fetches_into = True

    def __init__(
        self,
        spheres: np.ndarray,
        width: int,
        height: int,
        options: CudaOptions | None = None,
        shading: Shading | None = None,
        primitive: str = "sphere",
    ):
        require()
        options = self._options(options, shading)
        self.options = options
        self.accel, self.kernel, self.build = options.accel, options.kernel, options.build
        # the kind of primitive spheres' columns are (kernels/primitives' KINDS), and its kernels
        self.primitive = primitive
        self._programs = k = programs(primitive)
        self._kind = k.primitive
        if self.accel == "none" and self.kernel == "fast" and k.primitive is not sphere:
            raise RaybenchError(
                f"kernel 'fast': its cull is the sphere's; brute force over {k.primitive.NOUN} is the simple kernel "
                "(kernel='simple', --kernel simple)"
            )
        walk = options.walk
        # for a walk the tree chooses, replaced below once it has chosen
        self.block = options.block or DEFAULT_BLOCK[self.kernel or walk or "ray"]
        self.rays, self.staged, self.trip = options.rays, options.staged, options.trip
        free, _total = cuda.current_context().get_memory_info()
        if k.primitive is sphere:
            check_fits("cuda GPU", width, height, spheres.shape[1], free)
        else:  # a mesh's buffer, its tree and the frame, in one line where they do not fit
            check_fits("cuda GPU", width, height, 0, free)
            check_bvh_fits("cuda GPU", spheres.shape[1], free, self._device_bytes(spheres.shape[0]),
                           width * height * PIXEL_BYTES, k.primitive.NOUN)  # fmt: skip
        check_fits("host", width, height, 0, host_available_bytes(), HOST_PIXEL_BYTES)
        if self.accel == "bvh":
            if k.primitive is sphere:
                check_bvh_fits(
                    "cuda GPU",
                    spheres.shape[1],
                    free - spheres.shape[1] * 7 * 4,
                    self._device_bytes(0),
                    width * height * PIXEL_BYTES,
                )
            check_bvh_fits(
                "host",
                spheres.shape[1],
                host_available_bytes(),
                bvh_mod.BUILD_SPHERE_BYTES,
                width * height * HOST_PIXEL_BYTES,
                k.primitive.NOUN,
            )
        self.spheres = spheres
        self.width, self.height = width, height
        self.count = spheres.shape[1]
        # a frame's launches with their arguments converted once: numba-cuda's
        # conversion of a BVH kernel's arrays, every launch, fell inside the
        # kernel's timed span (cuda.launch;
        # docs/notes/startup.md#a-launchs-arguments-converted-once)
        self._launches = Launches(64)
        # a kind traced through its buffer in the tree's order (program.in_tree_order) has it on
        # the device once, made by _build; with a tree built on the host nothing is uploaded before
        self._in_order = self.accel == "bvh" and in_tree_order(k.primitive)
        self.d_spheres = None
        if not self._in_order or self.build == "gpu":
            self.d_spheres = self._scene_on_device()
        self.d_image = cuda.device_array((height, width, 3), dtype=np.uint8)
        self.d_hits = cuda.device_array((height, width), dtype=np.int32)
        self.image = self.host_array((height, width, 3), np.uint8)
        self.hits = self.host_array((height, width), np.int32)
        self.d_basis = cuda.device_array((4, 3), dtype=np.float32)
        self.constant_count = options.constant_count
        self.bvh = None
        self.build_s = None
        self._builder = None
        self._fresh_cost = None
        self.walk = None
        self.shading = shading
        self.schedule = options.schedule
        self._wavefront = None  # the wavefront's queues and launches (schedule "wavefront")
        self.ray_counts = None
        if shading is not None:
            self._kernel = k.program._whitted_kernel
            if self.schedule == "wavefront":
                self._wavefront = Wavefront(width, height, shading.depth, options.wave_grid, k.stages)
            if self.accel == "bvh":
                self._build(self.count)
                self.walk = "ray"
            else:  # brute force: a tree of no node
                self.d_nodes = cuda.device_array((0, NODE_FLOATS), np.float32)
                self.d_links = cuda.device_array((0, NODE_FLOATS), np.int32)
                self.d_nodes64 = self.d_nodes.view(np.float64)
                self.d_sphere_rows = cuda.device_array((1, 2), np.float64)  # read by no walk: there is no tree
                self.d_ordered = cuda.device_array((k.primitive.LEAF_ROWS, 1), np.float32)
                self.d_order = cuda.device_array(1, np.int32)
            if not self._in_order:  # else _build put them in the tree's order
                self.d_materials = cuda.to_device(shading.materials if self.count else np.ones((5, 1), np.float32))
            self.d_lights = cuda.to_device(shading.lights)
            self.d_pattern = cuda.to_device(shading.pattern)
            self.d_params = cuda.to_device(shading.params)
            self.d_rays = cuda.to_device(np.zeros(len(KINDS), np.int64))
            self.ray_counts = np.zeros(len(KINDS), np.int64)
        elif self.accel == "bvh":
            self._build(self.count)
            self.walk = choose_walk(self._rows_walked()) if walk is None else walk
            self._kernel = k.program._bvh_packet_kernel if self.walk == "packet" else k.program._bvh_kernel
            if options.block is None:
                self.block = DEFAULT_BLOCK[self.walk]
        elif self.kernel == "fast":
            self._kernel = k.program.fast_kernel(self.rays, self.staged, self.trip)
            self.d_relative = cuda.device_array((4, max(self.count, 1)), dtype=np.float32)
        else:
            self._kernel = k.program._constant_kernel(self.count) if self.constant_count else k.program._render_kernel
        self.grid = (math.ceil(width / self.block[0]), math.ceil(height / (self.block[1] * self.rays)))
        self._rows = None  # the rows the last launch traced, None for all

    def _device_bytes(self, rows: int) -> int:
        """Device bytes a primitive: its `rows` float32 of the scene's buffer
        (0: counted apart), its tree's (the GPU builder's arrays, or a host
        tree's rows, its leaf buffer and order) and the wavefront's packed
        copy of its leaf."""
        # the leaf buffer is the scene's buffer itself, where the kind is traced in the tree's order
        leaf = 0 if in_tree_order(self._kind) else 4 * self._kind.LEAF_ROWS
        # the sphere's figures count its leaf's four float32: 16 bytes
        tree = (cuda_build.DEVICE_SPHERE_BYTES if self.build == "gpu" else bvh_mod.DEVICE_SPHERE_BYTES) - 16 + leaf
        packed = row_bytes(self._kind) if self.options.schedule == "wavefront" else 0
        return 4 * rows + (tree + packed if self.accel == "bvh" else 0)

    def _build(self, count: int) -> None:
        """The BVH of the first `count` spheres, on the device: built on the
        host and uploaded, or built on the GPU (its arrays kept for the next
        build of as many spheres). build_s is the build alone: on the host
        without the upload (a copy like the spheres'), on the GPU up to the
        tree ready to walk."""
        if self.build == "gpu":
            if self._builder is None or self._builder.n != count:
                self._builder = (
                    cuda_build.Builder(
                        count,
                        quality=self.options.quality,
                        treelet_passes=self.options.treelet_passes,
                        kind=self._programs.build,
                    )
                    if count >= 2
                    else None
                )
            kind = self._programs.build
            self.bvh = cuda_build.build(self.spheres[:, :count], self._d_input(), self._builder, kind=kind)
            # the fresh tree's SAH cost: what update()'s refits are held to
            self._fresh_cost = self._builder.read_cost() if self.bvh.built_on == "gpu" else None
        else:
            cost = self._kind.CUDA_NODE_COST
            host = bvh_mod.build(self.spheres[:, :count], device="cuda", primitive=self._kind, node_cost=cost)
            if self._in_order:  # its nodes and order alone: the leaves are the scene's buffer, put in order below
                host = dataclasses.replace(host, ordered=np.zeros((1, 1), np.float32))
            self.bvh = cuda_build.upload(host)
        self._launches.clear()  # they hold the old tree's arrays
        self.build_s = self.bvh.build_s
        self.d_nodes, self.d_links = self.bvh.nodes, self.bvh.links  # the same bytes: one row holds both
        self.d_nodes64 = self.d_nodes.view(np.float64)  # the same again, as the wavefront reads a row
        self.d_ordered, self.d_order = self.bvh.ordered, self.bvh.order
        if self._in_order:
            start = time.perf_counter()
            self._put_in_order()
            if self.bvh.built_on == "gpu":  # part of the tree ready to walk; a host tree's is its upload
                self.build_s += time.perf_counter() - start
        self._sphere_rows()

    def _d_input(self):
        """The scene's buffer on the device in its own order, for the GPU's build."""
        if self._in_order:  # d_spheres is the last tree's order: let go, then uploaded again
            self.d_spheres = None
            self.d_spheres = self._scene_on_device()
        return self.d_spheres

    def _scene_on_device(self):
        """The scene's buffer copied to the device in its own order (a column of
        zeros for a scene of none, which no kernel reads)."""
        return cuda.to_device(self.spheres if self.count else np.zeros((self.spheres.shape[0], 1), np.float32))

    def _put_in_order(self) -> None:
        """The scene's buffer (and Whitted's materials) on the device in the
        tree's order, which the walks read as their leaves and the shading as
        the scene (program.in_tree_order); the buffer in its own order, which
        the GPU's build read, let go."""
        built_on_gpu = self.bvh.built_on == "gpu"
        d_rows = self.d_spheres if built_on_gpu else None
        self.d_spheres = None
        count = self.bvh.count
        # a mesh of one colour keeps its vertices' rows, and its colour once (layout's TRI_ROWS)
        last = self._kind.shared_colour(self.spheres[:, :count])
        self.d_spheres = put_in_tree_order(self.spheres, self.d_order, count, d_rows, last)
        self.d_ordered = self.d_spheres
        if self.shading is not None:
            self.d_materials = put_in_tree_order(self.shading.materials, self.d_order, count)

    def _sphere_rows(self) -> None:
        """The ordered spheres a row each, as the wavefront's walks read them
        (wavefront.sphere_rows), after each build or refit of the tree; None
        where no wavefront walks it."""
        packed = self._programs.wavefront.sphere_rows
        self.d_sphere_rows = packed(self.d_ordered, self._kind.PACKED_WORDS) if self._wavefront is not None else None

    def _rows_walked(self) -> int:
        """The rows of the tree a walk can reach: all of a host-built tree's;
        of the GPU's, those its collapsed subtrees left out of reach not
        counted (counted by cuda_build's bottom-up pass)."""
        if self.bvh.built_on == "gpu":
            return self._builder.read_rows()
        return self.bvh.node_count

    def update(self, spheres: np.ndarray) -> str | None:
        """The spheres moved (or changed radius or colour; as many as before):
        the next frames show spheres, a (7, N) float32 array like the first.
        Their tree follows: with build "gpu" refitted on the GPU (its shape
        kept, its boxes the spheres' new ones) while its SAH cost stays
        within options.refit_limit of its fresh cost, else rebuilt; with
        build "host" rebuilt on the host. Returns "refit" or "build" (None
        for brute force, which has no tree); build_s is what it took, the
        tree ready to walk. A mesh is traced as it was given."""
        if self.primitive != "sphere":
            raise RaybenchError(f"update: moves spheres; a scene of {self._kind.NOUN} is traced as it was given")
        self.spheres = check_moved(spheres, self.spheres)
        if self.count:
            self.d_spheres.copy_to_device(self.spheres)
        if self.accel != "bvh":
            return None
        refit_s = 0.0
        if self.build == "gpu" and self.bvh.built_on == "gpu":
            start = time.perf_counter()
            self._builder.launch_refit(self.d_spheres)
            cost = self._builder.read_cost()  # waits for the refit
            refit_s = time.perf_counter() - start
            if cost <= self.options.refit_limit * self._fresh_cost:
                self._sphere_rows()  # the refit moved the ordered spheres
                self.build_s = refit_s
                return "refit"
        self._build(self.bvh.count)
        self.build_s += refit_s  # the refit that was not enough, then the build
        return "build"

    def compile(self) -> float:
        """Compile the kernel if needed (one empty launch); the seconds it took."""
        start = time.perf_counter()
        self._launch((1, 1), 0, 0, self.count)
        cuda.synchronize()
        return time.perf_counter() - start

    def _launch(self, grid, width, height, count, first: int = 0, end: int | None = None) -> None:
        """The frame's kernel on grid, for rows first..end (default all) of a
        width x height frame."""
        end = height if end is None else end
        launch = self._launches
        with warnings.catch_warnings():
            # Small frames cannot fill the GPU; that is the user's choice, not news.
            warnings.simplefilter("ignore", NumbaPerformanceWarning)
            if self.shading is not None:
                if self.accel == "bvh" and self.bvh.count != count:
                    self._build(count)
                self._last = (grid, width, height, count, first, end)
                if self._wavefront is not None:
                    self._wavefront.launch(self, count, first, end)
                    return
                launch(_zero_rays, 1, len(KINDS), self.d_rays)
                launch(
                    self._kernel, grid, self.block, width, height, first, end, self.d_basis, self.d_spheres, count,
                    self.d_materials, self.d_lights, self.d_pattern, self.d_params, self.d_nodes, self.d_links,
                    self.d_ordered, self.d_order, self.d_image, self.d_hits, self.d_rays,
                )  # fmt: skip
            elif self.accel == "bvh":
                if self.bvh.count != count:  # a frame of fewer spheres: their own tree
                    self._build(count)
                launch(
                    self._kernel, grid, self.block, width, height, first, end, self.d_basis, self.d_nodes,
                    self.d_links, self.d_ordered, self.d_order, self.d_spheres, self.d_image, self.d_hits,
                )  # fmt: skip
            elif self.kernel == "fast":
                # EO and the cull bound for this frame's camera, on the GPU, before the frame
                launch(self._programs.program._prepare_kernel, max(1, math.ceil(count / 256)), 256, self.d_basis,
                       self.d_spheres, count, self.d_relative)  # fmt: skip
                launch(
                    self._kernel, grid, self.block, width, height, first, end, self.d_basis, self.d_spheres,
                    self.d_relative, count, self.d_image, self.d_hits,
                )  # fmt: skip
            else:
                launch(
                    self._kernel, grid, self.block, width, height, first, end, self.d_basis, self.d_spheres, count,
                    self.d_image, self.d_hits,
                )  # fmt: skip

    def _prepare(self, basis: np.ndarray, count: int | None) -> int:
        """Upload the camera; the sphere count to trace."""
        self.d_basis.copy_to_device(basis)
        return self.count if count is None else check_count(count, self.count, self.constant_count)

    def launch(self, basis: np.ndarray, count: int | None = None, rows: tuple[int, int] | None = None) -> None:
        """Start the kernel for one frame of the first `count` spheres (default
        all); it runs asynchronously. rows: (first, end), to trace only those
        rows of the frame (a cluster's tile)."""
        count = self._prepare(basis, count)
        if rows is None:
            self._rows = None
            self._launch(self.grid, self.width, self.height, count)
            return
        first, end = self._rows = check_rows(rows, self.height)
        grid = (self.grid[0], math.ceil((end - first) / (self.block[1] * self.rays)))
        self._launch(grid, self.width, self.height, count, first, end)

    def fetch(self) -> tuple[np.ndarray, np.ndarray]:
        """Copy the last frame (or its rows, where launch() was given rows)
        to the host (waits for the kernel)."""
        self._settle()
        if self._rows is not None:
            first, end = self._rows
            self.d_image[first:end].copy_to_host(self.image[first:end])
            self.d_hits[first:end].copy_to_host(self.hits[first:end])
        else:
            self.d_image.copy_to_host(self.image)
            self.d_hits.copy_to_host(self.hits)
        if self.ray_counts is not None:
            self.d_rays.copy_to_host(self.ray_counts)
        return self.image, self.hits

    def fetch_into(self, image_rows: np.ndarray, hit_rows: np.ndarray) -> None:
        """The rows of the last launch(rows=...) copied from the device
        straight into image_rows and hit_rows (host arrays of those rows'
        shapes, such as a frame's rows in shared memory, page-locked by pin()
        for a direct copy), not through this tracer's own buffers; waits for
        the kernel."""
        self._settle()
        first, end = self._rows
        self.d_image[first:end].copy_to_host(image_rows)
        self.d_hits[first:end].copy_to_host(hit_rows)
        if self.ray_counts is not None:
            self.d_rays.copy_to_host(self.ray_counts)

    def host_array(self, shape: tuple, dtype) -> np.ndarray:
        """A new array for frames, page-locked (not under the simulator): the
        copy from the device into it is one DMA (the contract's host_array)."""
        return np.empty(shape, dtype) if simulated() else cuda.pinned_array(shape, dtype=dtype)

    @staticmethod
    def pin(address: int, size: int):
        """The host memory at address page-locked for this device's copies as
        long as the returned object lives (None under the simulator): a copy
        from the device into it is then one DMA, not a copy into a pinned
        buffer of the driver's and another out of it."""
        if simulated():
            return None
        return cuda.current_context().mempin(None, address, size)

    def trace(
        self, basis: np.ndarray, count: int | None = None, rows: tuple[int, int] | None = None
    ) -> tuple[np.ndarray, np.ndarray]:
        self.launch(basis, count, rows)
        return self.fetch()

    def timed_trace(self, basis: np.ndarray, count: int | None = None) -> float | None:
        """trace(), returning the kernel's own time in ms (CUDA events around the
        launch alone; the camera upload and the copy back are outside). None
        under the simulator, which has no GPU clock to read."""
        if simulated():
            self.trace(basis, count)
            return None
        count = self._prepare(basis, count)
        self._rows = None
        start, end = cuda.event(), cuda.event()
        start.record()
        self._launch(self.grid, self.width, self.height, count)
        end.record()
        if self._wavefront is not None and self._wavefront.overflowed():
            # the queues were short for this frame: made longer, and the frame traced and timed again
            return self.timed_trace(basis, count)
        self.fetch()
        end.synchronize()
        return start.elapsed_time(end)

    def kernels(self) -> dict:
        """The compiled kernels a frame launches, by name: {"frame": ...}, or
        the wavefront's stages; for benchmarks that read their registers or
        their assembly."""
        return self._wavefront.kernels() if self._wavefront is not None else {"frame": self._kernel}

    @property
    def wavefront(self):
        """The Wavefront that traces this tracer's Whitted frames, None where
        they are traced a pixel a thread (its `mark` times its stages)."""
        return self._wavefront

    def _settle(self) -> None:
        """Where the wavefront's queues were short for the last frame, trace
        it again with longer ones until they hold it (waits for the frame)."""
        while self._wavefront is not None and self._wavefront.overflowed():
            self._launch(*self._last)

    def close(self) -> None:
        """Device buffers go with the object; nothing to release by hand."""
