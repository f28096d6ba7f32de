"""The BVH built on the GPU through wgpu: backends/cuda/build.py's LBVH
(Karras 2012) ported to WGSL compute shaders, in raybench.bvh's node layout,
so the walks read it unchanged. The same algorithm and arithmetic: the tree
is raybench.bvh.lbvh_model's, bit for bit (tests/test_wgpu_build.py).

The steps (the .wgsl pieces say how each is done in WGSL, and why where
it differs from cuda's kernels):
  build_codes.wgsl  the centres' box (bounds_parts, bounds_merge), each
                    centre's Morton code (morton);
  build_sort.wgsl   the LSD radix sort, PASSES passes of count, scan and scatter;
  build_tree.wgsl   Karras's hierarchy, then the bottom-up pass: boxes, SAH
                    leaf cuts, heights, the SAH cost, the ordered spheres.
A build is 5 + 3 * PASSES (20) dispatches in one compute pass (WebGPU makes
each dispatch's writes visible to the next), then one 16-byte read: the
tree's depth, for the guard below. A refit is two dispatches.

Only what every adapter has: no subgroups, no float atomics (floats travel
as their bits through u32 atomics), workgroups of THREADS (WebGPU's default
most) and at most 16 KiB of workgroup memory, 8 storage buffers a stage,
workgroups laid out in 2-D past 65535 a dimension.

Quality "sah" (lbvh.QUALITY, the default) or "lbvh", as cuda's; cuda's
"treelet" is not ported.

The walks' stack holds layout.STACK entries: a tree deeper than MAX_DEPTH
is replaced by the host's build (raybench.bvh), as on cuda; so is one of
under two spheres (no internal node to build).
"""

from __future__ import annotations

import functools
import math
import time
from dataclasses import dataclass
from importlib import resources

import numpy as np

from ... import bvh as bvh_mod
from ... import layout
from ...bvh import lbvh
from ...kernels.primitives import KINDS, sphere
from . import namespace

QUALITIES = ("sah", "lbvh")
# A workgroup: WebGPU's default most invocations.
THREADS = 256
# The sort: a workgroup sorts a tile of THREADS * ITEMS keys (keys and
# values in workgroup memory: 8 KiB of WebGPU's 16 KiB default, the scan's
# 4 KiB beside), DIGIT_BITS a pass (5 passes for 30 bits, as cuda's), the
# tile first sorted by the digit SPLIT_BITS at a time (a workgroup scan a
# round, its barriers the sort's floor: 3 bits, 8 buckets whose counts are
# packed two to a word, a vec4 of them; 1 and 2 work too, to be measured
# against: benchmarks/wgpu_build.py --split-bits).
ITEMS = 4
TILE = THREADS * ITEMS
DIGIT_BITS = 6
RADIX = 1 << DIGIT_BITS
PASSES = -(-lbvh.CODE_BITS // DIGIT_BITS)
SPLIT_BITS = 3
# The scan of a digit's counts over the tiles: SCAN_ITEMS an invocation,
# SCAN_CHUNK = THREADS * SCAN_ITEMS a round (one round up to 4,194,304 spheres).
SCAN_ITEMS = 4
# The centres' box: at most PARTS workgroups, merged by one.
PARTS = THREADS
PARTS_AT = 16  # where the parts start in the bounds buffer (after the box and the cells per unit)
MAX_GROUPS = 65535  # a dispatch's workgroups a dimension, WebGPU's default
STATS_BYTES = 16


def constants() -> str:
    """The WGSL constants, from their Python definitions (float32 values
    whose repr is exact)."""
    if SPLIT_BITS not in (1, 2, 3) or DIGIT_BITS % SPLIT_BITS or TILE >= 1 << 16:
        raise ValueError(f"SPLIT_BITS: 1, 2 or 3 dividing DIGIT_BITS ({DIGIT_BITS}), got {SPLIT_BITS}")
    values = {
        "THREADS": f"{THREADS}u",
        "ITEMS": f"{ITEMS}u",
        "TILE": f"{TILE}u",
        "SCAN_ITEMS": f"{SCAN_ITEMS}u",
        "SCAN_CHUNK": f"{THREADS * SCAN_ITEMS}u",
        "DIGIT_BITS": f"{DIGIT_BITS}u",
        "RADIX": f"{RADIX}u",
        "SPLIT_BITS": f"{SPLIT_BITS}u",
        "BUCKETS": f"{1 << SPLIT_BITS}u",
        "PARTS_AT": f"{PARTS_AT}u",
        "CELL_BITS": f"{lbvh.CODE_BITS // 3}u",
        "AXIS_CELLS": f"{lbvh.AXIS_CELLS}u",
        "BIG": "3.4028234663852886e38",  # float32's largest: WGSL may assume no infinities
        "PAD": repr(float(layout.PAD)),
        "NODE_COST": repr(float(bvh_mod.NODE_COST)),
        "NODE_WORDS": f"{layout.NODE_FLOATS}u",
        "BOX_WORDS": f"{layout.BOX_FLOATS}u",
        "REF": f"{layout.REF}u",
        "COUNT": f"{layout.COUNT}u",
        "INNER": f"{layout.INNER}",
    }
    return "".join(f"const {name} = {value};\n" for name, value in values.items())


# The steps that read the primitives' buffer (binding 1, which the sort binds to its keys).
READS_PRIMITIVES = ("build_codes.wgsl", "build_tree.wgsl")
# Each kind's answers to the builders (extent, leaf_row and the Leaf they
# write), and the constants those pieces take from Python: the triangle's
# box is the walks' (triangle_box.wgsl), over compute.py's rows.
KIND_PIECES = {
    "sphere": ("sphere_build.wgsl",),
    "triangle": ("triangle_box.wgsl", "triangle_build.wgsl"),
    "mixed": ("triangle_box.wgsl", "sphere_build.wgsl", "triangle_build.wgsl", "mixed_build.wgsl"),
}
# In the mixed kind's build, the sphere's and the triangle's pieces under
# prefixes, as shader.RENAMED in its tracer: mixed_build.wgsl declares the
# scene's buffer for both kinds and the sphere's reader of it; the box is
# triangle_box.wgsl's struct Extent, the very one the sphere's declares.
RENAMED = {
    "sphere_build.wgsl": {"prefix": "sphere_", "dropped": ("items", "Extent"), "replaced": ("read_sphere",)},
    "triangle_build.wgsl": {"prefix": "triangle_", "dropped": ("items",)},
}


# The float32 of a scene's row as compute.py lays it out for the tracer and
# the build alike (its TRIANGLE_FLOATS and MIXED_FLOATS, which import this
# module): a triangle's, and a mixed primitive's, a triangle's and the tag.
SCENE_WORDS = {"triangle": layout.TRI_SMOOTH_ROWS, "mixed": layout.TRI_SMOOTH_ROWS + 1}


def kind_constants(primitive: str) -> dict[str, str]:
    """The constants the kinds' pieces take from Python: the triangle's box
    is the walks' (triangle_box.wgsl), over the kind's rows (SCENE_WORDS),
    whose stride the triangle's readers take."""
    words = SCENE_WORDS["mixed" if primitive == "mixed" else "triangle"]
    return {
        "BVH_PAD": repr(float(layout.PAD)),
        "TRI_SCENE_WORDS": f"{words}u",
        "MIXED_SCENE_WORDS": f"{SCENE_WORDS['mixed']}u",
        "MIXED_SPHERE_TAG": repr(float(layout.MIX_SPHERE)),
        "MIXED_LEAF_WORDS": f"{layout.MIX_LEAF_ROWS}",
    }


def piece(name: str, primitive: str) -> str:
    """A piece's text as a kind's build takes it (RENAMED for the mixed kind's)."""
    text = resources.files(__package__).joinpath(name).read_text(encoding="utf-8")
    if primitive == "mixed" and name in RENAMED:
        return namespace.namespaced(text, **RENAMED[name])
    return text


@functools.cache
def source(step: str, primitive: str = "sphere") -> str:
    """The WGSL of one step's module: the constants, the common piece, the
    primitive's answers to the builders where the step reads primitives
    (the sort reads only codes), the step's."""
    answers = KIND_PIECES[primitive] if step in READS_PRIMITIVES else ()
    names = ("build_common.wgsl", *answers, step)
    text = constants() + "\n".join(piece(p, primitive) for p in names)
    for name, value in kind_constants(primitive).items():
        text = text.replace(name, value)
    return text


def grid(groups: int) -> tuple[int, int]:
    """Workgroups in 2-D, at most MAX_GROUPS a side (the kernels skip those past the end)."""
    groups = max(groups, 1)
    x = min(groups, MAX_GROUPS)
    return x, math.ceil(groups / x)


class Kernels:
    """The build's pipelines on one device for a kind of primitive
    (KIND_PIECES' keys), compiled once; leaf_rows: the float32 of a row of
    the tree's leaf buffer that they write (the kind's LEAF_ROWS)."""

    ENTRIES = {
        "build_codes.wgsl": ("bounds_parts", "bounds_merge", "morton"),
        "build_sort.wgsl": ("count", "scan", "scatter"),
        "build_tree.wgsl": ("hierarchy", "reset", "bounds_up"),
    }

    def __init__(self, device, primitive: str = "sphere"):
        self.device = device
        self.primitive, self.leaf_rows = primitive, KINDS[primitive].LEAF_ROWS
        self.pipelines = {}
        for step, entries in self.ENTRIES.items():
            module = device.create_shader_module(code=source(step, primitive))
            for entry in entries:
                self.pipelines[entry] = device.create_compute_pipeline(
                    layout="auto", compute={"module": module, "entry_point": entry}
                )

    def bind(self, entry: str, buffers: dict) -> object:
        """A bind group for entry: binding number -> buffer."""
        pipeline = self.pipelines[entry]
        return self.device.create_bind_group(
            layout=pipeline.get_bind_group_layout(0),
            entries=[{"binding": b, "resource": {"buffer": buf}} for b, buf in buffers.items()],
        )


def _params(n: int, shift: int, leaf_max: int, sah: int, parts: int) -> bytes:
    tiles = math.ceil(n / TILE)
    return np.array([n, shift, tiles, 0, leaf_max, sah, parts, 0], np.uint32).tobytes()


@dataclass
class Stats:
    """What the bottom-up pass leaves: the root's height (the tree's depth),
    the rows a walk reaches, the SAH cost (bvh.cost.sah_cost's, summed in
    float32 as the model does)."""

    depth: int
    rows: int
    cost: float


class Builder:
    """Builds (and refits) trees of the first n spheres of a device's sphere
    buffer (compute.py's rows of 8 floats), or of the primitives of the kind
    its kernels are for (compute.py's rows of that kind), its buffers and
    bind groups made once and reused by every build and refit: the dynamic
    case builds every frame. quality and leaf_size as cuda_build.Builder's."""

    def __init__(self, device, spheres, n: int, leaf_size: int | None = None, quality: str | None = None,
                 kernels: Kernels | None = None):  # fmt: skip
        import wgpu

        quality = lbvh.QUALITY if quality is None else quality
        if quality not in QUALITIES:
            raise ValueError(f"quality: must be one of {', '.join(QUALITIES)}, got {quality!r}")
        if n < 2:
            raise ValueError(f"n: the GPU builds trees of 2 spheres or more, got {n}")
        self.device, self.n, self.quality = device, n, quality
        self.leaf_size = (
            leaf_size if leaf_size is not None else (lbvh.LEAF_SIZE if quality == "lbvh" else bvh_mod.LEAF_MAX)
        )
        self.kernels = kernels if kernels is not None else Kernels(device)
        m = n - 1
        self.tiles = math.ceil(n / TILE)
        self.parts = min(math.ceil(n / THREADS), PARTS)
        storage = wgpu.BufferUsage.STORAGE | wgpu.BufferUsage.COPY_SRC

        def buffer(size: int):
            return device.create_buffer(size=max(size, 4), usage=storage)

        self.bounds = buffer(4 * (PARTS_AT + 6 * PARTS))
        self.keys = (buffer(4 * n), buffer(4 * n))
        self.values = (buffer(4 * n), buffer(4 * n))
        self.hist = buffer(4 * RADIX * (self.tiles + 1))  # the counts, then the digits' totals
        self.nodes = buffer(layout.NODE_BYTES * m)
        self.links = buffer(4 * (m + n + 2 * m))  # up, leaf_up, span
        self.scratch = device.create_buffer_with_data(data=np.zeros(7 * m, np.uint32).tobytes(), usage=storage)
        self.ordered = buffer(4 * self.kernels.leaf_rows * n)
        self.stats = buffer(STATS_BYTES)
        self.stats_read = device.create_buffer(
            size=STATS_BYTES, usage=wgpu.BufferUsage.COPY_DST | wgpu.BufferUsage.MAP_READ
        )
        # the sorted values end in the buffer the last pass wrote: the leaf order
        self.keys_sorted = self.keys[PASSES % 2]
        self.order = self.values[PASSES % 2]
        sah = int(quality != "lbvh")

        def uniform(shift: int, leaf_max: int):
            return device.create_buffer_with_data(
                data=_params(n, shift, leaf_max, sah, self.parts), usage=wgpu.BufferUsage.UNIFORM
            )

        passes = [uniform(p * DIGIT_BITS, self.leaf_size) for p in range(PASSES)]
        params, refit = passes[0], uniform(0, 0)
        bind = self.kernels.bind
        self._codes = [
            ("bounds_parts", bind("bounds_parts", {0: params, 1: spheres, 2: self.bounds}), (self.parts, 1)),
            ("bounds_merge", bind("bounds_merge", {0: params, 2: self.bounds}), (1, 1)),
            ("morton", bind("morton", {0: params, 1: spheres, 2: self.bounds, 3: self.keys[0], 4: self.values[0]}),
             grid(math.ceil(n / THREADS))),
        ]  # fmt: skip
        self._sort = []
        for p in range(PASSES):
            src, dst = p % 2, 1 - p % 2
            self._sort += [
                ("count", bind("count", {0: passes[p], 1: self.keys[src], 3: self.hist}), grid(self.tiles)),
                ("scan", bind("scan", {0: passes[p], 3: self.hist}), (RADIX, 1)),
                ("scatter", bind("scatter", {0: passes[p], 1: self.keys[src], 2: self.values[src], 3: self.hist,
                                             4: self.keys[dst], 5: self.values[dst]}), grid(self.tiles)),
            ]  # fmt: skip
        tree = {4: self.nodes, 5: self.links, 6: self.scratch}
        up = {1: spheres, 3: self.order, **tree, 7: self.ordered, 8: self.stats}
        self._hierarchy = [
            ("hierarchy", bind("hierarchy", {0: params, 2: self.keys_sorted, **tree}), grid(math.ceil(m / THREADS)))
        ]
        self._up = [("bounds_up", bind("bounds_up", {0: params, **up}), grid(math.ceil(n / THREADS)))]
        self._refit = [
            ("reset", bind("reset", {0: refit, 4: self.nodes, 6: self.scratch}), grid(math.ceil(m / THREADS))),
            ("bounds_up", bind("bounds_up", {0: refit, **up}), grid(math.ceil(n / THREADS))),
        ]

    def steps(self) -> dict[str, list]:
        """A build's dispatches by step, in order: (entry, bind group, workgroups)."""
        return {"codes": self._codes, "sort": self._sort, "hierarchy": self._hierarchy, "bounds": self._up}

    def encode(self, encoder, dispatches, timestamp_writes=None) -> None:
        """dispatches in one compute pass."""
        compute_pass = encoder.begin_compute_pass(timestamp_writes=timestamp_writes)
        for entry, group, (x, y) in dispatches:
            compute_pass.set_pipeline(self.kernels.pipelines[entry])
            compute_pass.set_bind_group(0, group)
            compute_pass.dispatch_workgroups(x, y, 1)
        compute_pass.end()

    def encode_build(self, encoder) -> None:
        self.encode(encoder, [d for step in self.steps().values() for d in step])

    def encode_refit(self, encoder, timestamp_writes=None) -> None:
        """The boxes of the tree's rows recomputed from the spheres' positions
        now (its shape kept), its cost and depth the refitted tree's."""
        self.encode(encoder, self._refit, timestamp_writes)

    def run(self, encode) -> Stats:
        """Submit encode(encoder)'s work and wait for its stats."""
        encoder = self.device.create_command_encoder()
        encode(encoder)
        encoder.copy_buffer_to_buffer(self.stats, 0, self.stats_read, 0, STATS_BYTES)
        self.device.queue.submit([encoder.finish()])
        return self.read_stats()

    def read_stats(self) -> Stats:
        import wgpu

        self.stats_read.map_sync(wgpu.MapMode.READ)
        try:
            words = np.frombuffer(self.stats_read.read_mapped(), np.uint32).copy()
        finally:
            self.stats_read.unmap()
        c, a = words[2:4].view(np.float32)
        # a scene whose areas overflow float32 has cost inf / inf: NaN, as the
        # model's (bvh.lbvh_steps), without NumPy's warning for it
        with np.errstate(invalid="ignore"):
            return Stats(int(words[0]), int(words[1]), float(c / a) if a > 0 else 0.0)

    def read(self, buffer, dtype, shape=None) -> np.ndarray:
        """A buffer's contents (for tests and checks)."""
        data = np.frombuffer(self.device.queue.read_buffer(buffer), dtype).copy()
        return data if shape is None else data[: int(np.prod(shape))].reshape(shape)

    def to_host(self, depth: int, build_s: float = 0.0) -> bvh_mod.Bvh:
        """The tree copied to the host, as raybench.bvh's Bvh."""
        nodes = self.read(self.nodes, np.float32, (self.n - 1, layout.NODE_FLOATS))
        ordered = self.read(self.ordered, np.float32, (self.n, self.kernels.leaf_rows))
        return bvh_mod.Bvh(
            nodes=nodes,
            links=nodes.view(np.int32),
            ordered=np.ascontiguousarray(ordered.T),
            order=self.read(self.order, np.int32, (self.n,)),
            depth=depth,
            build_s=build_s,
        )


@dataclass
class Tree:
    """The tree the walk binds: the GPU's buffers, or the host's uploaded."""

    nodes: object  # wgpu buffers
    ordered: object
    order: object
    count: int
    depth: int
    build_s: float
    built_on: str  # "gpu", or "host" (under two spheres, or the GPU's tree too deep)
    cost: float | None = None  # the SAH cost the GPU summed (None for the host's)


def upload(device, b: bvh_mod.Bvh) -> Tree:
    """A host-built tree on the device (one row at least of each: a binding cannot be empty)."""
    import wgpu

    usage = wgpu.BufferUsage.STORAGE | wgpu.BufferUsage.COPY_SRC
    ordered = np.zeros((max(b.count, 1), b.ordered.shape[0]), np.float32)
    ordered[: b.count] = b.ordered.T
    order = b.order if b.count else np.zeros(1, np.int32)
    return Tree(
        device.create_buffer_with_data(data=b.nodes.tobytes(), usage=usage),
        device.create_buffer_with_data(data=ordered.tobytes(), usage=usage),
        device.create_buffer_with_data(data=order.tobytes(), usage=usage),
        b.count,
        b.depth,
        b.build_s,
        "host",
    )


def build(device, spheres: np.ndarray, builder: Builder | None, max_depth: int = layout.MAX_DEPTH,
          primitive=sphere) -> Tree:  # fmt: skip
    """The tree of the (7, N) spheres, whose rows are builder's sphere
    buffer, built on the GPU by builder (for N spheres), or on the host where
    there is none (N < 2) or its tree is deeper than max_depth. build_s: from
    the submission to the tree ready to walk (its depth read back).
    primitive: the kind's module (kernels/primitives) the columns are, for the
    host's build."""
    n = spheres.shape[1]
    if builder is None or n < 2:
        return upload(device, bvh_mod.build(spheres, device="wgpu", primitive=primitive))
    if builder.n != n:
        raise ValueError(f"builder: built for {builder.n} spheres, given {n}")
    start = time.perf_counter()
    stats = builder.run(builder.encode_build)
    if stats.depth > max_depth:
        return upload(device, bvh_mod.build(spheres, device="wgpu", primitive=primitive))
    seconds = time.perf_counter() - start
    return Tree(builder.nodes, builder.ordered, builder.order, n, stats.depth, seconds, "gpu", stats.cost)
