"""The CPU's Tracer: a frame's rows spread over a pool of threads, each
running a compiled kernel with the GIL released (backends/cpu says how)."""

from __future__ import annotations

import dataclasses
import time
from concurrent import futures
from concurrent.futures import ThreadPoolExecutor

import numba
import numpy as np

from ... import bvh as bvh_mod
from ... import layout
from ...errors import RaybenchError
from ...host import host_available_bytes, usable_cores
from ...kernels.packets import PACKET_H
from ...kernels.primitives import triangle, triangle_mesh
from ...layout import (
    NODE_COST,
    NODE_FLOATS,
)
from ...lighting import Shading
from ...meshes import Painted
from ..contract import TracerBase, check_moved
from ..limits import HOST_PIXEL_BYTES, check_bvh_fits, check_count, check_fits, check_rows
from ..options import KIND_TREE_WIDTH, CpuOptions
from .kinds import primitive_of, programs

# Chunks of rows per thread for the BVH: enough that the last chunk to finish
# leaves the others little time idle, few enough that the calls cost little.
CHUNKS_PER_THREAD = 16


def chunks(height: int, threads: int) -> list[tuple[int, int]]:
    """Rows 0..height in about CHUNKS_PER_THREAD chunks per thread, in order,
    cut at whole packets of rows."""
    packets = -(-height // PACKET_H)
    return [
        (a * PACKET_H, min(b * PACKET_H, height)) for a, b in bands(packets, min(packets, threads * CHUNKS_PER_THREAD))
    ]


def default_threads() -> int:
    return usable_cores()


def description() -> str:
    return f"cpu ({default_threads()} threads, Numba {numba.__version__})"


def bands(height: int, threads: int) -> list[tuple[int, int]]:
    """Split rows 0..height into `threads` contiguous bands whose sizes differ by at most one."""
    edges = [height * i // threads for i in range(threads + 1)]
    return [(a, b) for a, b in zip(edges, edges[1:]) if b > a]


_bands_of = bands  # Tracer.trace's name for it, where a local shadows bands


class Tracer(TracerBase):
    """Renders one scene at one size, frame after frame, into reused buffers
    (the contract: backends.contract.Tracer)."""

    name = "cpu"
    traces_rows = True

    def __init__(
        self,
        spheres: np.ndarray,
        width: int,
        height: int,
        options: CpuOptions | None = None,
        shading: Shading | None = None,
        primitive: str = "sphere",
    ):
        options = self._options(options, shading)
        self.options = options
        self.accel, self.kernel = options.accel, options.kernel
        # a painted mesh's packets of primary rays read its tree, built from its own arrays, and
        # its one colour alone: no scene buffer is made, and a large one that shares its vertices
        # is read through the tree's order, no leaf buffer either (kernels/primitives/triangle_mesh.py);
        # every other frame reads the scene buffer
        self._source = None
        if isinstance(spheres, Painted):
            packets = (options.tree_width or KIND_TREE_WIDTH.get(primitive, {}).get("thesis")) == 4
            if self.accel == "bvh" and shading is None and packets:
                self._source, self._colour = spheres.arrays(), triangle.colour_column(spheres.colour)
            else:
                spheres = spheres.leaves()
        count = len(spheres) if self._source is not None else spheres.shape[1]
        # the kind of primitive spheres' columns are (kernels/primitives' KINDS), and its kernels
        self.primitive = primitive
        self._kind = primitive_of(primitive)
        self._programs = programs(primitive)
        if self.accel == "none" and self.kernel == "fast" and self._programs.fast_band is None:
            raise RaybenchError(
                f"kernel 'fast': its cull is the sphere's; brute force over {self._kind.NOUN} is the simple kernel "
                "(kernel='simple', --kernel simple)"
            )
        # the threads' stacks counted: under ulimit -v they take address space the frame then lacks
        check_fits("cpu", width, height, count, host_available_bytes(options.threads), HOST_PIXEL_BYTES)
        if self.accel == "bvh":
            check_bvh_fits(
                "cpu",
                count,
                host_available_bytes(),
                bvh_mod.BUILD_SPHERE_BYTES,
                width * height * HOST_PIXEL_BYTES,
                self._kind.NOUN,
            )
        self.threads = options.threads
        self.spheres = spheres if self._source is None else None
        self.count = count
        self.width, self.height = width, height
        self.image = np.empty((height, width, 3), dtype=np.uint8)
        self.hits = np.empty((height, width), dtype=np.int32)
        self.constant_count = options.constant_count
        self.bvh = None
        self.build_s = None
        self.shading = shading
        self.ray_counts = None
        self.tree_width = None  # the packets' tree: with the BVH
        self._none = np.zeros((0, NODE_FLOATS), np.float32)  # no nodes: brute force's tree, a let-go binary tree
        if shading is not None:
            # rows take unequal time (mirrors and glass cost more): pulled in chunks, as the BVH's
            self.bands = chunks(height, self.threads)
            workers = min(self.threads, len(self.bands))
            if self.accel == "bvh":
                # 4: the primary and shadow rays as packets through the 4-wide
                # tree, the bounces through it alone (_whitted_rows_packets); 2:
                # every ray alone through the binary tree
                self.tree_width = options.tree_width or KIND_TREE_WIDTH[primitive]["whitted"]
            self._kernel = self._programs.whitted["packets" if self.tree_width == 4 else self.accel]
            self._row_rays = np.zeros((height, len(layout.KINDS)), np.int64)
            self.ray_counts = np.zeros(len(layout.KINDS), np.int64)
            if self.accel == "bvh":
                self._build(self.count)
        elif self.accel == "bvh":
            self.shaded = self._shaded()
            self.bands = chunks(height, self.threads)
            workers = min(self.threads, len(self.bands))
            self.tree_width = options.tree_width or KIND_TREE_WIDTH[primitive]["thesis"]
            self._kernel = self._programs.packets if self.tree_width == 4 else self._programs.rows
            self._build(self.count)
        else:
            self.bands = bands(height, self.threads)
            workers = len(self.bands)
            if self.kernel == "fast":
                self._kernel = self._programs.fast_band
                self.relative = np.zeros((4, self.count), np.float32)
            else:
                brute = self._programs
                self._kernel = brute.constant_band(self.count) if self.constant_count else brute.render_band
        # Every band is traced on the pool's threads, a single one too: the
        # main thread only waits, so that Ctrl-C reaches it mid-frame (trace).
        self._pool = ThreadPoolExecutor(workers)
        self._workers = workers
        self._stop = np.zeros(1, np.uint8)  # set: every kernel returns at its next row (trace)

    def _shaded(self) -> np.ndarray:
        """What the packets of primary rays shade from (_colour_packet): the scene buffer, or a
        painted mesh's colour column; with no primitive, a stand-in that every pixel misses
        (a miss reads primitive 0), as the cuda backend uploads."""
        if self._source is not None:
            return self._colour
        return self.spheres if self.count else self._stand_in()

    def _stand_in(self) -> np.ndarray:
        """A buffer of one primitive of the kind, for a frame of none."""
        return np.zeros((self._kind.SCENE_ROWS, 1), np.float32)

    def update(self, spheres: np.ndarray) -> str | None:
        """The spheres moved: the next frames trace them, through a tree
        rebuilt on the host (the contract's update)."""
        if self.primitive != "sphere":
            raise RaybenchError(f"update: moves spheres; a scene of {self._kind.NOUN} is traced as it was given")
        self.spheres = check_moved(spheres, self.spheres)
        if self.accel != "bvh":
            return None
        if self.shading is None:
            self.shaded = self._shaded()
        self._build(self.bvh.count)
        return "build"

    def _build(self, count: int) -> None:
        """The BVH of the first `count` spheres; its build time in build_s
        (with the collapse into 4-wide nodes, where the packets walk those)."""
        threads = min(self.threads, default_threads())
        # a tree that only the packets of primary rays walk is cut for them (the kind's PACKETS_NODE_COST)
        packets_only = self.shading is None and self.tree_width == 4
        node_cost = self._kind.PACKETS_NODE_COST if packets_only else NODE_COST
        if self._source is None:
            items, kind = self.spheres[:, :count], self._kind
        else:
            items, kind = triangle_mesh.first(self._source, count), triangle_mesh
        self.bvh = bvh_mod.build(items, threads=threads, primitive=kind, node_cost=node_cost)
        self.build_s = self.bvh.build_s
        if self.tree_width == 4:
            if not bvh_mod.collapse_in_python(self.bvh):
                bvh_mod.compile_collapse()
            start = time.perf_counter()
            self.wide = bvh_mod.collapse(self.bvh)
            self.build_s += time.perf_counter() - start
            # every walk of this width reads the 4-wide tree (the packets, Whitted's bounces and
            # its shadow packets): the binary tree's nodes, about as large, are let go
            self.bvh = dataclasses.replace(self.bvh, nodes=self._none, links=self._none.view(np.int32))

    def _tree(self, count):
        """The BVH's arrays for the walk; brute force's stand-in, with no node."""
        if self.accel == "none":
            return (self._none, self._none.view(np.int32), np.zeros((4, 0), np.float32), np.zeros(0, np.int32))
        if self.bvh.count != count:  # a frame of fewer spheres: their own tree
            self._build(count)
        b = self.bvh
        if self.tree_width == 4:
            return (b.nodes, b.links, b.ordered, b.order, self.wide, self.wide.view(np.int32))
        return (b.nodes, b.links, b.ordered, b.order)

    def _args(self, basis, count):
        return (*self._kernel_args(basis, count), self._stop)

    def _kernel_args(self, basis, count):
        if self.shading is not None:
            w = self.shading
            return (self.width, self.height, basis, self.spheres, count, w.materials, w.lights, w.pattern, w.params,
                    self._tree(count), self.image, self.hits, self._row_rays)  # fmt: skip
        if self.accel == "bvh":
            if self.bvh.count != count:  # a frame of fewer spheres: their own tree
                self._build(count)
            b = self.bvh
            nodes = self.wide if self.tree_width == 4 else b.nodes
            return (
                self.width,
                self.height,
                basis,
                nodes,
                nodes.view(np.int32),
                b.ordered,
                b.order,
                self.shaded,
                self.image,
                self.hits,
            )
        if self.kernel == "fast":
            self._programs.prepare(basis, self.spheres, count, self.relative)
            return (self.width, self.height, basis, self.spheres, self.relative, count, self.image, self.hits)
        return (self.width, self.height, basis, self.spheres, count, self.image, self.hits)

    def compile(self) -> float:
        """Compile the kernel if needed, tracing nothing; the seconds it took."""
        start = time.perf_counter()
        self._kernel(0, 0, *self._args(np.zeros((4, 3), np.float32), self.count))
        return time.perf_counter() - start

    def trace(
        self, basis: np.ndarray, count: int | None = None, rows: tuple[int, int] | None = None
    ) -> tuple[np.ndarray, np.ndarray]:
        """Trace a frame of the first `count` spheres (default all) into
        self.image and self.hits, which are reused between frames. rows:
        (first, end), to trace only those rows of the frame (a tile of a
        cluster's render: raybench.cluster); the others are left as they were.
        first must be a multiple of PACKET_H, so that the BVH's packets fall
        on the rows the whole frame's would."""
        count = self.count if count is None else check_count(count, self.count, self.constant_count)
        args = self._args(basis, count)
        first, end, bands = 0, self.height, self.bands
        if rows is not None:
            first, end = check_rows(rows, self.height, PACKET_H)
            cut = chunks if self.accel == "bvh" or self.shading is not None else _bands_of
            bands = [(first + a, first + b) for a, b in cut(end - first, self.threads)]
        if self._pool is None:  # closed, and used again
            self._pool = ThreadPoolExecutor(self._workers)
        if self.accel == "bvh" or self.shading is not None:
            pending = iter(bands)  # next() on it is atomic under the GIL

            def pull():
                for a, b in pending:
                    self._kernel(a, b, *args)

            jobs = [self._pool.submit(pull) for _ in range(self._workers)]
        else:
            jobs = [self._pool.submit(self._kernel, a, b, *args) for a, b in bands]
        self._finish(jobs)
        if self.ray_counts is not None:
            self.ray_counts[:] = self._row_rays[first:end].sum(axis=0)
        return self.image, self.hits

    def _finish(self, jobs) -> None:
        """Wait for the frame's bands. Ctrl-C (or a band's error) meanwhile:
        the kernels still running are told to stop, return at their next row,
        and are awaited before it goes on, so that no thread writes into
        the buffers of an abandoned frame (or the next one); a second Ctrl-C
        while they return is not let out, as the wait is a row's time."""
        try:
            for job in jobs:
                job.result()
        except BaseException:
            self._stop[0] = 1
            while True:
                try:
                    futures.wait(jobs)
                    break
                except KeyboardInterrupt:
                    continue
            raise
        finally:
            self._stop[0] = 0

    def timed_trace(self, basis: np.ndarray, count: int | None = None) -> float | None:
        """trace(); the CPU has no separate kernel time to report: None."""
        self.trace(basis, count)
        return None

    def close(self) -> None:
        if self._pool is not None:
            self._pool.shutdown()
            self._pool = None
