"""Whitted shading on CUDA by ray, not by pixel: kernels/wavefront.py's
stages, each a kernel over a queue, a wave a bounce.

A frame: the primary rays into the first queue; then for each bounce up to
the depth, three launches: extend (each ray's nearest hit), shade (the
light that needs no ray, shadow rays into the shadow queue, children into
the next wave's queue) and shadow (any hit along each shadow ray); then the
pixels' summed light into bytes. The counts of the queues stay on the GPU:
the host launches every stage of every wave at once and waits only for the
frame, and a stage reads how many rays its queue holds where it runs.

Slots in a queue are claimed a block at a time: each thread adds its
rays' number to a counter in shared memory, then one thread claims the
block's total from the queue's count with one global atomic. A queue that
would overflow keeps the count of the rays it was asked to hold; the frame
is then traced again with queues that fit (Wavefront.overflowed), so no
ray is ever lost.

A frame whose queues would not fit in the GPU's free memory is traced in
bands of rows (backends/bands.py), their launches one after another on the
stream, each band's counts its own: the same picture, still with no wait
between launches.

A stage's kernel is launched on `grid` blocks of BLOCK threads, each thread
taking the rays i, i + the grid's threads, ... of the queue: by default
GRID_PER_SM blocks a multiprocessor, more than it holds at once, each
thread looping over its share (persistent threads). A grid of a thread a
ray measured slower: most of its blocks find their wave's queue short of
them and exit, a launch's worth of blocks for nothing, at every stage
(docs/notes/whitted.md).
"""

from __future__ import annotations

import functools
import math
from types import SimpleNamespace

import numpy as np
from numba import cuda
from numba.cuda import libdevice

from ... import compiled, kernels
from ...kernels.primitives import sphere
from ...kernels.wavefront import R_KIND, R_PIXEL, RAY_IDS, RAY_ROWS, SHADOW_IDS, SHADOW_ROWS
from ...layout import CHILD_BOX, COUNT, KINDS, NODE_FLOATS, PRIMARY, REF, STACK
from .. import bands
from .device import simulated
from .launch import Launches
from .program import in_tree_order

if simulated():  # numba's simulator runs these as Python, where libdevice's bit casts are stubs

    @cuda.jit(device=True)
    def _words(w):
        """A float64 load's two float32 words (the low one the lower column)."""
        words = np.array([w], np.float64).view(np.float32)
        return words[0], words[1]

    @cuda.jit(device=True)
    def _ints(w):
        """A float64 load's two int32 words (the low one the lower column)."""
        words = np.array([w], np.float64).view(np.int32)
        return words[0], words[1]

else:

    @cuda.jit(device=True)
    def _words(w):
        """A float64 load's two float32 words (the low one the lower column)."""
        return libdevice.int_as_float(libdevice.double2loint(w)), libdevice.int_as_float(libdevice.double2hiint(w))

    @cuda.jit(device=True)
    def _ints(w):
        """A float64 load's two int32 words (the low one the lower column)."""
        return libdevice.double2loint(w), libdevice.double2hiint(w)


@cuda.jit(device=True)
def _read_row64(nodes64, _links, row):
    """traverse.make's read_row for a node's row seen as 8 float64
    (nodes64, layout's row as pairs of columns): 8 loads a row where
    float32 columns take 16, each word taken out as it was stored (bit
    casts, no arithmetic), the refs and counts as ints."""
    a_lx, a_ly = _words(nodes64[row, np.uint64(0)])
    a_lz, a_hx = _words(nodes64[row, np.uint64(1)])
    a_hy, a_hz = _words(nodes64[row, np.uint64(2)])
    b_lx, b_ly = _words(nodes64[row, np.uint64(3)])
    b_lz, b_hx = _words(nodes64[row, np.uint64(4)])
    b_hy, b_hz = _words(nodes64[row, np.uint64(5)])
    a_ref, b_ref = _ints(nodes64[row, np.uint64(6)])
    a_count, b_count = _ints(nodes64[row, np.uint64(7)])
    return a_lx, a_ly, a_lz, a_hx, a_hy, a_hz, b_lx, b_ly, b_lz, b_hx, b_hy, b_hz, a_ref, b_ref, a_count, b_count


@compiled.cuda_jit()
def _sphere_rows(ordered, rows):
    """bvh.ordered (a row a field) as a row a primitive, the layout that the
    primitive's leaf tests read through _words (kernels/primitives): the
    primitive's pack_leaf."""
    k = cuda.grid(1)
    if k < ordered.shape[1]:
        _pack_leaf(ordered, k, rows)


def row_bytes(primitive=sphere) -> int:
    """Device bytes a primitive of sphere_rows' copy: its PACKED_WORDS float64."""
    return 8 * primitive.PACKED_WORDS


# Device bytes a sphere of sphere_rows' copy.
SPHERE_ROW_BYTES = row_bytes()


def sphere_rows(d_ordered, words: int = sphere.PACKED_WORDS):
    """The ordered primitives as the wavefront's walks read them
    (_sphere_rows), `words` float64 a primitive (its PACKED_WORDS), made on
    the device after each build or refit."""
    n = d_ordered.shape[1]
    rows = cuda.device_array((n, 2 * words), np.float32)
    _sphere_rows[max(1, math.ceil(n / BLOCK)), BLOCK](d_ordered, rows)
    return rows.view(np.float64)


# _read_row64's words are layout's columns in this order
assert NODE_FLOATS == 16 and CHILD_BOX == (0, 6) and REF == 12 and COUNT == 14


# the wavefront's walks read a row in 8 wide loads (_read_row64; the Tracer
# passes its nodes as float64), not 16, and a leaf's sphere in 2, not 4
# (the primitive's read_leaf through _words, the spheres a row each, from
# sphere_rows): the walk is bound by issue, and
# a load is an instruction (docs/notes/whitted.md)
# Made for a primitive, the sphere's at import; compiled.rebound compiles
# this module's kernels again for another kind (backends/cuda/kinds.py).
@functools.cache
def _made(primitive=sphere):
    """kernels.make for the wavefront, for one kind of primitive."""
    return kernels.make(
        cuda.jit(device=True), read_row=_read_row64, words=_words, primitive=primitive,
        positions=in_tree_order(primitive),
    )  # fmt: skip


_k = _made()
# module globals, which is how kernels can see them: the stages through the
# tree and by brute force (only extend and the shadow test search)
_tree, _every = _k.whitted_wavefront["bvh"], _k.whitted_wavefront["none"]
_extend_tree, _extend_every = _tree.extend, _every.extend
_unblocked_tree, _unblocked_every = _tree.unblocked, _every.unblocked
_emit_primary, _missed, _shade_ray = _tree.emit_primary, _tree.missed, _tree.shade
_put_shadows, _put_children = _tree.put_shadows, _tree.put_children
_fixed, _resolve, _to_byte, _original = _tree.fixed, _tree.resolve, _k.to_byte, _k.original
_pack_leaf = _k.prim.pack_leaf


@cuda.jit(device=True)
def _extend_ray(rays_f, rays_i, i, spheres, count, nodes, links, ordered, order, stack_row, stack_t):
    """The nearest hit of queued ray i: through the tree, or every sphere
    where the frame has none (the same choice in every thread)."""
    tree = (nodes, links, ordered, order)
    if nodes.shape[0] > 0:
        return _extend_tree(rays_f, rays_i, i, spheres, count, tree, stack_row, stack_t)
    return _extend_every(rays_f, rays_i, i, spheres, count, tree, stack_row, stack_t)


@cuda.jit(device=True)
def _unblocked_ray(shadows_f, shadows_i, i, spheres, count, nodes, links, ordered, order, stack_row, stack_t):
    """Whether queued shadow ray i reaches its light, as _extend_ray walks."""
    tree = (nodes, links, ordered, order)
    if nodes.shape[0] > 0:
        return _unblocked_tree(shadows_f, shadows_i, i, spheres, count, tree, stack_row, stack_t)
    return _unblocked_every(shadows_f, shadows_i, i, spheres, count, tree, stack_row, stack_t)


BLOCK = 128
GRID_PER_SM = 32
# Queues start at this many rays a pixel traced (the rays of a wave; the
# shadow rays of a wave), and double when a frame finds them short.
RAYS_A_PIXEL = 1
SHADOWS_A_PIXEL = 2
# Where the counts live: counts[wave] rays in wave's queue, counts[SHADOW_BASE
# + wave] shadow rays cast in that wave, counts[OVERFLOW] set where a queue
# was too short.
MAX_WAVES = 18
SHADOW_BASE = MAX_WAVES
OVERFLOW = 2 * MAX_WAVES
COUNTS = OVERFLOW + 1
# Device bytes a slot: a ray in both queues (floats, ints) and its hit; a shadow ray.
RAY_BYTES = 2 * (RAY_ROWS + RAY_IDS) * 4 + 12
SHADOW_BYTES = (SHADOW_ROWS + SHADOW_IDS) * 4
QUEUES = [bands.Buffer(ray=RAY_BYTES, shadow=SHADOW_BYTES)]
# The share of the GPU's free memory the queues may take: the rest for the
# driver and whatever else runs there.
FREE_SHARE = 0.9


@cuda.jit(device=True)
def _claim(n, shared, counts, which, capacity):
    """The first of n slots for this thread in the queue whose count is
    counts[which] (module docstring); every thread of the block calls it.
    Flags counts[OVERFLOW] where the block's slots run past capacity."""
    mine = 0
    if n > 0:
        mine = cuda.atomic.add(shared, 0, n)
    cuda.syncthreads()
    if cuda.threadIdx.x == 0:
        total = shared[0]
        shared[0] = 0
        start = 0
        if total > 0:
            start = cuda.atomic.add(counts, which, total)
            if start + total > capacity:
                counts[OVERFLOW] = 1
        shared[1] = start
    cuda.syncthreads()
    first = shared[1] + mine
    cuda.syncthreads()  # shared[1] is read by all before the next claim writes it
    return first


@cuda.jit(device=True)
def _add(accum, pixel, red, green, blue):
    """A pixel's light += (red, green, blue), as integers (kernels/wavefront.py)."""
    if red != 0:
        cuda.atomic.add(accum, (0, pixel), _fixed(red))
    if green != 0:
        cuda.atomic.add(accum, (1, pixel), _fixed(green))
    if blue != 0:
        cuda.atomic.add(accum, (2, pixel), _fixed(blue))


@compiled.cuda_jit()
def _start(counts, rays, tally):
    """A band's counts zeroed, and the ray tally where `tally` (the frame's
    first band; its pixels' sums were zeroed by the last frame's _finish)."""
    i = cuda.grid(1)
    if i < COUNTS:
        counts[i] = 0
    if tally and i < len(KINDS):
        rays[i] = 0


@compiled.cuda_jit()
def _primary(rays_f, rays_i, counts, first_pixel, pixels, width, height, basis):
    i = cuda.grid(1)
    if i == 0:
        counts[0] = pixels
    if i < pixels:
        _emit_primary(rays_f, rays_i, i, first_pixel + i, width, height, basis)


# Registers capped: more blocks resident on a multiprocessor hide more of the
# walk's latency, which bounds it (docs/notes/whitted.md#the-wavefront-issue-27)
@compiled.cuda_jit(max_registers=56)
def _extend(rays_f, rays_i, counts, wave, capacity, spheres, count, nodes, links, ordered, order, hit_i, hit_t,
            hit_d, hits, width, rays):  # fmt: skip
    """Each ray's nearest hit; the primary rays' into `hits`; the rays by
    kind into `rays` (a block's tally, then one atomic a kind)."""
    tally = cuda.shared.array(4, np.int32)
    me = cuda.threadIdx.x
    if me < 4:
        tally[me] = 0
    cuda.syncthreads()
    n = min(counts[wave], capacity)
    stack_row = cuda.local.array(STACK, np.int32)
    stack_t = cuda.local.array(STACK, np.float32)
    i = cuda.grid(1)
    while i < n:
        h, t, d = _extend_ray(rays_f, rays_i, i, spheres, count, nodes, links, ordered, order, stack_row, stack_t)
        hit_i[i] = h
        hit_t[i] = t
        hit_d[i] = d
        kind = rays_i[R_KIND, i]
        if kind == PRIMARY:
            pixel = rays_i[R_PIXEL, i]
            hits[pixel // width, pixel % width] = _original(h, order) if nodes.shape[0] > 0 else h
        cuda.atomic.add(tally, kind, 1)
        i += cuda.gridsize(1)
    cuda.syncthreads()
    if me < 4 and me != 1 and tally[me] > 0:
        cuda.atomic.add(rays, me, np.int64(tally[me]))


@compiled.cuda_jit()
def _shade(rays_f, rays_i, counts, wave, capacity, hit_i, hit_t, hit_d, next_f, next_i, next_capacity, shadows_f,
           shadows_i, shadow_capacity, spheres, materials, lights, pattern, params, width, max_depth,
           accum):  # fmt: skip
    """Each ray's hit shaded: its light that needs no ray into its pixel,
    its shadow rays into the shadow queue, its children into the next."""
    shared = cuda.shared.array(2, np.int32)
    if cuda.threadIdx.x == 0:
        shared[0] = 0
    cuda.syncthreads()
    n = min(counts[wave], capacity)
    base = cuda.blockIdx.x * cuda.blockDim.x
    while base < n:  # the same trips in every thread of the block: _claim's barriers
        i = base + cuda.threadIdx.x
        h = -1
        n_shadows = 0
        n_children = 0
        px = py = pz = nx = ny = nz = cos_i = keep = kr = kt = tx = ty = tz = slack_r = slack_t = np.float32(0.0)
        inside = cast_r = cast_t = False
        if i < n:
            h = hit_i[i]
            pixel = rays_i[R_PIXEL, i]
            if h < 0:
                red, green, blue = _missed(rays_f, rays_i, i, width, params)
            else:
                (red, green, blue, n_shadows, px, py, pz, nx, ny, nz, cos_i, inside, keep, kr, kt, tx, ty, tz,
                 cast_r, slack_r, cast_t, slack_t) = _shade_ray(
                    rays_f, rays_i, i, h, hit_t[i], hit_d[i], max_depth, spheres, materials, lights, pattern, params
                )  # fmt: skip
                n_children = (1 if cast_r else 0) + (1 if cast_t else 0)
            _add(accum, pixel, red, green, blue)
        first_shadow = _claim(n_shadows, shared, counts, SHADOW_BASE + wave, shadow_capacity)
        first_child = _claim(n_children, shared, counts, wave + 1, next_capacity)
        if n_shadows > 0:
            _put_shadows(shadows_f, shadows_i, first_shadow, shadow_capacity, rays_f, rays_i, i, h, px, py, pz,
                              nx, ny, nz, inside, keep, spheres, materials, lights, pattern, params)  # fmt: skip
        if n_children > 0:
            _put_children(next_f, next_i, first_child, next_capacity, rays_f, rays_i, i, h, px, py, pz, nx, ny,
                               nz, cos_i, inside, kr, kt, tx, ty, tz, cast_r, slack_r, cast_t, slack_t)  # fmt: skip
        base += cuda.gridsize(1)


@compiled.cuda_jit()
def _shadow(shadows_f, shadows_i, counts, wave, capacity, spheres, count, nodes, links, ordered, order, accum,
            rays):  # fmt: skip
    """Each shadow ray of the wave: its light into its pixel where no
    sphere blocks it."""
    n = min(counts[SHADOW_BASE + wave], capacity)
    if cuda.grid(1) == 0 and n > 0:
        cuda.atomic.add(rays, 1, np.int64(n))
    stack_row = cuda.local.array(STACK, np.int32)
    stack_t = cuda.local.array(STACK, np.float32)
    i = cuda.grid(1)
    while i < n:
        free = _unblocked_ray(shadows_f, shadows_i, i, spheres, count, nodes, links, ordered, order, stack_row,
                              stack_t)  # fmt: skip
        if free:
            _add(accum, shadows_i[0, i], shadows_f[7, i], shadows_f[8, i], shadows_f[9, i])
        i += cuda.gridsize(1)


@compiled.cuda_jit()
def _finish(accum, first_pixel, pixels, width, image):
    """The pixels' summed light into bytes, and the sums zeroed for the
    next frame (a pass over them the frame's start need not make)."""
    i = cuda.grid(1)
    if i < pixels:
        pixel = first_pixel + i
        y = pixel // width
        x = pixel % width
        for c in range(3):
            image[y, x, c] = _to_byte(_resolve(accum[c, pixel]))
            accum[c, pixel] = 0


def _stages() -> SimpleNamespace:
    """A frame's kernels: this module's, or in a copy for another kind of
    primitive (compiled.rebound) the copy's own."""
    return SimpleNamespace(start=_start, primary=_primary, extend=_extend, shade=_shade, shadow=_shadow,
                           finish=_finish)  # fmt: skip


class Wavefront(bands.Queues):
    """The queues of a cuda Tracer's Whitted frames, kept between frames,
    and the launches of one frame. grid: the blocks a stage runs on (None:
    as many as its queue's capacity needs, a thread a ray). mark: None, or
    a function called with a stage's name after each launch (each wave's
    extend, shade and shadow, and "start" and "finish"), for a benchmark to
    record a CUDA event there (benchmarks/archive/wavefront_stages.py).
    stages: the kernels of a kind of primitive (_stages of its copy of this
    module: backends/cuda/kinds.py), by default the sphere's."""

    shadow_base, overflow = SHADOW_BASE, OVERFLOW  # the columns of d_counts

    def __init__(self, width: int, height: int, depth: int, grid: int | None = None, stages=None):
        self.width, self.height, self.depth = width, height, depth
        self.stages = _stages() if stages is None else stages
        self.grid = _default_grid() if grid is None else grid
        pixels = width * height
        self.d_accum = cuda.to_device(np.zeros((3, max(pixels, 1)), np.int64))
        self.queues = None
        self.ray_capacity = self.shadow_capacity = 0
        self._allocate(self._plan(height, pixels * RAYS_A_PIXEL, pixels * SHADOWS_A_PIXEL))
        self.retraced = 0  # frames traced again with longer queues
        self._bands = 1  # the bands of the last frame, whose counts overflowed() reads
        self.mark = None

    def _plan(self, rows: int, rays: int, shadows: int) -> bands.Plan:
        """Queues for rays and shadows slots that `rows` rows need (bands.plan),
        in the GPU's free memory (less a margin) and the memory the queues
        now hold."""
        if simulated():
            limit, holds = bands.capped(2**62), "the queues' limit"
        else:
            free, _total = cuda.current_context().get_memory_info()
            held = QUEUES[0].bytes(self.ray_capacity, self.shadow_capacity, 0)
            limit = bands.capped(int((free + held) * FREE_SHARE))
            holds = f"the GPU's free memory ({limit / 2**30:.1f} GiB for the queues)"
        if bands.QUEUE_BYTES is not None and limit == bands.QUEUE_BYTES:
            holds = f"the queues' limit ({limit / 2**20:.1f} MiB)"
        return bands.plan(self.width, rows, rays, shadows, QUEUES, limit, BLOCK, holds)

    def _allocate(self, plan: bands.Plan) -> None:
        self.plan = plan
        rays, shadows = plan.rays, plan.shadows
        count = math.ceil(self.height / plan.rows)
        # a band's launches are kept apart from another's: their counts differ
        self._launches = Launches(16 * (MAX_WAVES + 2) * count)
        self.d_counts = cuda.device_array((count, COUNTS), np.int32)
        self._counts = [self.d_counts[k] for k in range(count)]
        self.queues = None  # the old ones go first
        self.d_hit_i = self.d_hit_t = self.d_hit_d = self.d_shadows_f = self.d_shadows_i = None
        self.ray_capacity, self.shadow_capacity = rays, shadows
        self.queues = [
            (cuda.device_array((RAY_ROWS, rays), np.float32), cuda.device_array((RAY_IDS, rays), np.int32))
            for _ in range(2)
        ]
        self.d_hit_i = cuda.device_array(rays, np.int32)
        self.d_hit_t = cuda.device_array(rays, np.float32)
        self.d_hit_d = cuda.device_array(rays, np.float32)
        self.d_shadows_f = cuda.device_array((SHADOW_ROWS, shadows), np.float32)
        self.d_shadows_i = cuda.device_array((SHADOW_IDS, shadows), np.int32)
        self._launches.clear()

    def _blocks(self, capacity: int) -> int:
        return max(1, min(self.grid, math.ceil(capacity / BLOCK)))

    def launch(self, tracer, count: int, first: int, end: int) -> None:
        """Every launch of one frame of rows first..end, on tracer's buffers
        (spheres, tree, shading, image, hits, ray tally): a band's after
        another's where the queues hold fewer rows (self.plan)."""
        rows = self.plan.bands(first, end) or [(first, end)]  # no rows (Tracer.compile): every kernel once
        self._bands = len(rows)
        for band, (top, bottom) in enumerate(rows):
            self._launch_band(tracer, count, top, bottom, self._counts[band], band == 0)

    def _launch_band(self, tracer, count: int, first: int, end: int, counts, tally: bool) -> None:
        """Every launch of rows first..end, its queues' counts in `counts`;
        the frame's ray tally zeroed first where `tally`."""
        launch, k = self._launches, self.stages
        width = self.width
        first_pixel, pixels = first * width, (end - first) * width
        launch(k.start, 1, COUNTS, counts, tracer.d_rays, tally)
        rays_f, rays_i = self.queues[0]
        launch(k.primary, max(1, math.ceil(pixels / BLOCK)), BLOCK, rays_f, rays_i, counts, first_pixel, pixels,
               width, self.height, tracer.d_basis)  # fmt: skip
        mark = self.mark or _unmarked
        mark("start")
        tree = (tracer.d_nodes64, tracer.d_links, tracer.d_sphere_rows, tracer.d_order)
        ray_blocks = self._blocks(self.ray_capacity)
        shadow_blocks = self._blocks(self.shadow_capacity)
        for wave in range(self.depth + 1):
            rays_f, rays_i = self.queues[wave % 2]
            next_f, next_i = self.queues[(wave + 1) % 2]
            launch(k.extend, ray_blocks, BLOCK, rays_f, rays_i, counts, wave, self.ray_capacity,
                   tracer.d_spheres, count, *tree, self.d_hit_i, self.d_hit_t, self.d_hit_d, tracer.d_hits, width,
                   tracer.d_rays)  # fmt: skip
            mark("extend")
            launch(k.shade, ray_blocks, BLOCK, rays_f, rays_i, counts, wave, self.ray_capacity, self.d_hit_i,
                   self.d_hit_t, self.d_hit_d, next_f, next_i, self.ray_capacity, self.d_shadows_f,
                   self.d_shadows_i, self.shadow_capacity, tracer.d_spheres, tracer.d_materials, tracer.d_lights,
                   tracer.d_pattern, tracer.d_params, width, self.depth, self.d_accum)  # fmt: skip
            mark("shade")
            launch(k.shadow, shadow_blocks, BLOCK, self.d_shadows_f, self.d_shadows_i, counts, wave,
                   self.shadow_capacity, tracer.d_spheres, count, *tree, self.d_accum, tracer.d_rays)  # fmt: skip
            mark("shadow")
        launch(k.finish, max(1, math.ceil(pixels / BLOCK)), BLOCK, self.d_accum, first_pixel, pixels, width,
               tracer.d_image)  # fmt: skip
        mark("finish")

    def kernels(self) -> dict:
        """The stages' kernels by name (Tracer.kernels)."""
        return {"extend": self.stages.extend, "shade": self.stages.shade, "shadow": self.stages.shadow}

    def _read_counts(self) -> np.ndarray:
        """The last frame's bands' queue counts (bands.Queues.overflowed), waiting for it."""
        return self.d_counts.copy_to_host()[: self._bands]


def _default_grid() -> int:
    """GRID_PER_SM blocks on each of the device's multiprocessors (numba's
    simulator: one block)."""
    return 1 if simulated() else cuda.get_current_device().MULTIPROCESSOR_COUNT * GRID_PER_SM


def _unmarked(_stage: str) -> None:
    pass
