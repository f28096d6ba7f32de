"""The CUDA Tracer: its kernels (the per-pixel functions of raybench.kernels,
compiled as CUDA device functions), their launches and their buffers."""

from __future__ import annotations

import functools
import math
import time
import warnings

import numpy as np
from numba import cuda
from numba.cuda.core.errors import NumbaPerformanceWarning

from ... import bvh as bvh_mod
from ... import compiled, kernels
from ...host import host_available_bytes
from ...kernels.constants import FAR, ZERO
from ...kernels.whitted import RAY_FLOATS, RAY_INTS, RAY_STACK
from ...layout import CHILD_BOX, INNER, KINDS, NODE_BYTES, NODE_FLOATS, RADIUS, STACK
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
from ..options import DEFAULT_BLOCK, RAYS_PER_THREAD, STAGED, TRIP, CudaOptions, checked
from . import build as cuda_build
from .device import require, simulated
from .launch import Launches
from .wavefront import SPHERE_ROW_BYTES, Wavefront, sphere_rows

# The walk by default: packets once the tree outgrows the L1 cache (256 KiB
# an SM on the GPUs measured): the packets cost more node visits than a ray
# at a time and save fetches, so they pay once the tree is fetched from L2;
# measured, the two crossed as the tree outgrew L1
# (docs/bvh-walk.md#packets-of-rays-on-the-gpu-leases-g-to-i-kept).
PACKET_TREE_BYTES = 256 * 1024


def choose_walk(nodes: int) -> str:
    """The walk for a tree of `nodes` rows, when the user did not choose."""
    return "packet" if nodes * NODE_BYTES > PACKET_TREE_BYTES else "ray"


_k = kernels.make(cuda.jit(device=True))
# module globals, which is how kernels can see them
_render_pixel, _primary_ray, _store_pixel = _k.render_pixel, _k.primary_ray, _k.store_pixel
_prepare_one, _may_hit, _along, _intersect_relative = _k.prepare, _k.may_hit, _k.along, _k.intersect_relative
_render_pixel_bvh = _k.render_pixel_bvh
_ray_axes, _children, _leaf_hits, _centre = _k.ray_axes, _k.children, _k.leaf_hits, _k.centre_along

_U = np.uint64


@compiled.cuda_jit()
def _render_kernel(width, height, first, end, basis, spheres, count, image, hits):
    x, y = cuda.grid(2)
    y += first
    if x < width and y < end:
        _render_pixel(x, y, width, height, basis, spheres, count, image, hits)


# STACK is imported as a plain global, which numba-cuda takes as a
# compile-time constant (a local array's size must be one); layout.STACK, a
# module attribute, is typed as a run-time int64 and fails on a real GPU (the
# simulator accepts either).


@compiled.cuda_jit()
def _bvh_kernel(width, height, first, end, basis, nodes, links, ordered, order, spheres, image, hits):
    x, y = cuda.grid(2)
    y += first
    if x < width and y < end:
        stack_row = cuda.local.array(STACK, np.int32)
        stack_t = cuda.local.array(STACK, np.float32)
        _render_pixel_bvh(
            x, y, width, height, basis, nodes, links, ordered, order, spheres, image, hits, stack_row, stack_t
        )


@cuda.jit(device=True)
def _tally(tally, primary, shadow, reflection, refraction):
    """Add a pixel's rays by kind to the block's tally, in shared memory."""
    cuda.atomic.add(tally, 0, primary)
    if shadow:
        cuda.atomic.add(tally, 1, shadow)
    if reflection:
        cuda.atomic.add(tally, 2, reflection)
    if refraction:
        cuda.atomic.add(tally, 3, refraction)


@cuda.jit(device=True)
def _flush(tally, me, rays):
    """Once every thread of the block has added its rays: rays += the tally,
    one global atomic per kind and block, not per pixel."""
    cuda.syncthreads()
    if me < 4:
        cuda.atomic.add(rays, me, np.int64(tally[me]))


_whitted_bvh_pixel, _whitted_all_pixel = _k.render_pixel_whitted["bvh"], _k.render_pixel_whitted["none"]


# Whitted shading, a thread a pixel (kernels/whitted.py), through the tree or,
# where it has no node, by brute force: one kernel holding both programs (a
# kernel cannot take the program as an argument, and a factory's closure
# would miss the cache, cpu.py says why); the choice is the same in every
# thread. rays[kind] += the rays the block cast (_tally, _flush).
@compiled.cuda_jit()
def _whitted_kernel(width, height, first, end, basis, spheres, count, materials, lights, pattern, params, nodes,
                    links, ordered, order, image, hits, rays):  # fmt: skip
    x, y = cuda.grid(2)
    y += first
    me = cuda.threadIdx.y * cuda.blockDim.x + cuda.threadIdx.x
    tally = cuda.shared.array(4, np.int32)
    if me < 4:
        tally[me] = 0
    cuda.syncthreads()
    if x < width and y < end:
        stack_row = cuda.local.array(STACK, np.int32)
        stack_t = cuda.local.array(STACK, np.float32)
        rays_f = cuda.local.array((RAY_STACK, RAY_FLOATS), np.float32)
        rays_i = cuda.local.array((RAY_STACK, RAY_INTS), np.int32)
        tree = (nodes, links, ordered, order)
        if nodes.shape[0] > 0:
            primary, shadow, reflection, refraction = _whitted_bvh_pixel(
                x, y, width, height, basis, spheres, count, materials, lights, pattern, params, tree, stack_row,
                stack_t, rays_f, rays_i, image, hits,
            )  # fmt: skip
        else:
            primary, shadow, reflection, refraction = _whitted_all_pixel(
                x, y, width, height, basis, spheres, count, materials, lights, pattern, params, tree, stack_row,
                stack_t, rays_f, rays_i, image, hits,
            )  # fmt: skip
        _tally(tally, primary, shadow, reflection, refraction)
    _flush(tally, me, rays)


@compiled.cuda_jit()
def _zero_rays(rays):
    rays[cuda.threadIdx.x] = 0


# What a thread pushes as the entry distance of a child its ray does not
# enter: beyond any closest hit, so it never votes to visit that child.
_MISS = np.float32(np.inf)


@compiled.cuda_jit()
def _bvh_packet_kernel(width, height, first, end, basis, nodes, links, ordered, order, spheres, image, hits):
    """The BVH walk with the block's rays as one packet, as the CPU walks its
    packets: the packet visits a node if any of its rays enters it, and each
    ray tests only the leaves it enters itself, so the node, the stack's rows
    and every branch are the same in all the block's threads: one node fetch
    serves them all, and they never diverge. The children are taken in the
    order of their centres along the block's central ray (faster than voting
    on the order: docs/bvh-walk.md#packets-of-rays-on-the-gpu-leases-g-to-i-kept).
    The votes are the block's
    barriers (syncthreads_or), which the CUDA simulator has too, so the
    tests run this very code; in a one-warp block (8x4, the default) they
    cost what warp votes do (measured). Every thread takes part in every
    vote: those off the image trace a copy of its last row or column,
    unstored. Same pixels as the ray-at-a-time walk:
    a ray's hit is in a box it enters, and the packet enters every box one
    of its rays does (or, off the stack, one it entered nearer than its
    closest hit)."""
    x, y = cuda.grid(2)
    y += first
    dx, dy, dz = _primary_ray(min(x, width - 1), min(y, end - 1), width, height, basis)
    cdx, cdy, cdz = _primary_ray(
        min(cuda.blockIdx.x * cuda.blockDim.x + cuda.blockDim.x // 2, width - 1),
        min(first + cuda.blockIdx.y * cuda.blockDim.y + cuda.blockDim.y // 2, end - 1),
        width,
        height,
        basis,
    )
    ox, oy, oz = basis[0, 0], basis[0, 1], basis[0, 2]
    ix, iy, iz, lx, ly, lz, hx, hy, hz = _ray_axes(ox, oy, oz, dx, dy, dz)
    stack_row = cuda.local.array(STACK, np.int32)  # the same in every thread
    stack_t = cuda.local.array(STACK, np.float32)  # where this thread's ray enters the node
    closest = FAR
    hit = -1
    hit_d = ZERO
    row = 0
    top = _U(0)
    while row >= 0:
        node = _U(row)
        a_near, a_far, b_near, b_far, a_ref, b_ref, a_count, b_count = _children(
            nodes, links, node, ix, iy, iz, lx, ly, lz, hx, hy, hz
        )
        a_in = a_near <= a_far and a_far > ZERO and a_near <= closest
        b_in = b_near <= b_far and b_far > ZERO and b_near <= closest
        # first the child whose box centre lies nearer along the block's
        # central ray: an order the same in every thread without a vote
        # (guarding an empty child's case with a branch, or clamping its
        # planes, cost more than the builder storing them finite:
        # docs/bvh-walk.md). The
        # barriers take int32 predicates on a GPU.
        b_first = _centre(nodes, node, _U(CHILD_BOX[1]), ox, oy, oz, cdx, cdy, cdz) < _centre(
            nodes, node, _U(CHILD_BOX[0]), ox, oy, oz, cdx, cdy, cdz
        )
        any_a = cuda.syncthreads_or(np.int32(a_in)) != 0
        any_b = cuda.syncthreads_or(np.int32(b_in)) != 0
        if b_first:
            a_near, a_ref, a_count, a_in, any_a, b_near, b_ref, b_count, b_in, any_b = (
                b_near,
                b_ref,
                b_count,
                b_in,
                any_b,
                a_near,
                a_ref,
                a_count,
                a_in,
                any_a,
            )
        row = -1
        if any_a:
            if a_count == INNER:
                row = a_ref
            elif a_in:
                closest, hit, hit_d = _leaf_hits(
                    ox, oy, oz, dx, dy, dz, ordered, order, a_ref, a_count, closest, hit, hit_d
                )
        if any_b:
            if b_count != INNER:
                if b_in and b_near <= closest:
                    closest, hit, hit_d = _leaf_hits(
                        ox, oy, oz, dx, dy, dz, ordered, order, b_ref, b_count, closest, hit, hit_d
                    )
            elif row < 0:
                row = b_ref
            else:
                stack_row[top] = b_ref
                stack_t[top] = b_near if b_in else _MISS
                top += _U(1)
        while row < 0 and top > _U(0):
            top -= _U(1)
            if cuda.syncthreads_or(np.int32(stack_t[top] <= closest)) != 0:
                row = stack_row[top]
    if x < width and y < end:
        _store_pixel(x, y, hit, hit_d, spheres, image, hits)


@cuda.jit
def _prepare_kernel(basis, spheres, count, relative):
    i = cuda.grid(1)
    if i < count:
        _prepare_one(i, basis, spheres, relative)


@functools.cache
def fast_kernel(rays: int = RAYS_PER_THREAD, staged: int = STAGED, trip: int = TRIP):
    """The fast kernel for `rays` pixels per thread, `staged` spheres staged
    in shared memory at a time and `trip` spheres per trip of the cull loop
    (compile-time constants: the per-thread arrays must have a fixed size to
    live in registers); one compilation per combination."""
    slots = staged + trip - 1  # room for the pads of a batch that is not a whole number of trips

    @cuda.jit(device=True)
    def farthest(ex, ey, ez, dx, dy, dz, v):
        """The largest v = EO.dir over the thread's rays: a tree of maxima,
        log2(rays) deep rather than a chain of rays - 1."""
        for j in range(rays):
            v[j] = _along(ex, ey, ez, dx[j], dy[j], dz[j])
        step = 1
        while step < rays:
            for j in range(0, rays - step, 2 * step):
                v[j] = max(v[j], v[j + step])
            step *= 2
        return v[0]

    @cuda.jit(device=True)
    def nearer(i, ex, ey, ez, s, r, dx, dy, dz, closest, hit, hit_d):
        """Sphere i's cull and exact tests on each of the thread's rays."""
        for j in range(rays):
            if _may_hit(ex, ey, ez, s, dx[j], dy[j], dz[j]):
                t, d = _intersect_relative(ex, ey, ez, r, dx[j], dy[j], dz[j])
                if t < closest[j] and t > ZERO:
                    closest[j] = t
                    hit[j] = i
                    hit_d[j] = d

    @cuda.jit
    def kernel(width, height, first, end, basis, spheres, relative, count, image, hits):
        """`rays` pixels per thread; the block walks the spheres `staged` at a
        time through shared memory, each thread scanning them two at a time with
        the cull test on all its rays and stopping for the exact test only
        where the cull cannot rule a hit out. Same arithmetic, same order of
        spheres, same pixels as _render_kernel."""
        if width <= 0 or end <= first:  # compile()'s empty launch; the same for every thread
            return
        sx = cuda.shared.array(slots, np.float32)
        sy = cuda.shared.array(slots, np.float32)
        sz = cuda.shared.array(slots, np.float32)
        ss = cuda.shared.array(slots, np.float32)
        dx = cuda.local.array(rays, np.float32)
        dy = cuda.local.array(rays, np.float32)
        dz = cuda.local.array(rays, np.float32)
        closest = cuda.local.array(rays, np.float32)
        hit = cuda.local.array(rays, np.int32)
        hit_d = cuda.local.array(rays, np.float32)
        v = cuda.local.array(rays, np.float32)
        vmax = cuda.local.array(trip, np.float32)
        bw, bh = cuda.blockDim.x, cuda.blockDim.y
        x = cuda.blockIdx.x * bw + cuda.threadIdx.x
        y0 = first + cuda.blockIdx.y * bh * rays + cuda.threadIdx.y
        for j in range(rays):
            y = min(y0 + j * bh, end - 1)  # rays past the rows asked for trace a copy of the last, unstored
            dx[j], dy[j], dz[j] = _primary_ray(min(x, width - 1), y, width, height, basis)
            closest[j] = FAR
            hit[j] = -1
            hit_d[j] = ZERO
        # Unsigned indices: a signed one makes every shared-memory read check
        # for Python's negative indexing (step 4 of docs/floors.md#each-version-against-the-floor).
        me = _U(cuda.threadIdx.y * bw + cuda.threadIdx.x)
        total = _U(count)
        for base in range(_U(0), total, _U(staged)):
            n = min(_U(staged), total - base)
            cuda.syncthreads()  # every thread is done with the previous batch
            for k in range(me, n, _U(bw * bh)):
                sx[k] = relative[0, base + k]
                sy[k] = relative[1, base + k]
                sz[k] = relative[2, base + k]
                ss[k] = relative[3, base + k]
            if me == _U(0):
                # pad to whole trips with spheres no ray can pass the cull test of
                for k in range(n, (n + _U(trip - 1)) // _U(trip) * _U(trip)):
                    sx[k], sy[k], sz[k], ss[k] = ZERO, ZERO, ZERO, FAR
            cuda.syncthreads()
            k = _U(0)
            while k < n:
                # `trip` spheres a trip, one branch for all on the farthest v
                # of all the thread's rays: the loop is then mostly arithmetic
                # (docs/floors.md#each-version-against-the-floor has what each
                # step bought).
                while k < n:
                    for q in range(trip):
                        vmax[q] = farthest(sx[k + _U(q)], sy[k + _U(q)], sz[k + _U(q)], dx, dy, dz, v)
                    passed = False
                    for q in range(trip):
                        passed |= vmax[q] > ss[k + _U(q)]
                    if passed:
                        break
                    k += _U(trip)
                for i in range(k, min(k + _U(trip), n)):
                    nearer(
                        base + i, sx[i], sy[i], sz[i], ss[i], spheres[RADIUS, base + i], dx, dy, dz, closest, hit, hit_d
                    )
                k += _U(trip)
        if x < width:
            for j in range(rays):
                y = y0 + j * bh
                if y < end:
                    _store_pixel(x, y, hit[j], hit_d[j], spheres, image, hits)

    return kernel


@functools.cache
def _constant_kernel(count: int):
    """_render_kernel with the sphere count frozen into the code (a compile-time
    constant, as in the thesis's tests 1 to 6); one compilation per count."""

    @cuda.jit
    def render_kernel(width, height, first, end, basis, spheres, _count, image, hits):
        x, y = cuda.grid(2)
        y += first
        if x < width and y < end:
            _render_pixel(x, y, width, height, basis, spheres, count, image, hits)

    return render_kernel


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
    ):
        """options: the device's (backends.options.checked("cuda", ...); None
        for the defaults); shading: the Shading of a Whitted frame, None for
        the thesis's shading."""
        require()
        if options is None:
            options = checked("cuda", {}, shading)
        self.options = options
        self.accel, self.kernel, self.build = options.accel, options.kernel, options.build
        walk = options.walk
        # for a walk the tree chooses, replaced below once it has chosen
        self.block = options.block or DEFAULT_BLOCK[self.kernel or walk or "ray"]
        self.rays, self.staged, self.trip = options.rays, options.staged, options.trip
        free, _total = cuda.current_context().get_memory_info()
        check_fits("cuda GPU", width, height, spheres.shape[1], free)
        check_fits("host", width, height, 0, host_available_bytes(), HOST_PIXEL_BYTES)
        if self.accel == "bvh":
            check_bvh_fits(
                "cuda GPU",
                spheres.shape[1],
                free - spheres.shape[1] * 7 * 4,
                (cuda_build.DEVICE_SPHERE_BYTES if self.build == "gpu" else bvh_mod.DEVICE_SPHERE_BYTES)
                + (SPHERE_ROW_BYTES if options.schedule == "wavefront" else 0),  # the wavefront's copy of the spheres
                width * height * PIXEL_BYTES,
            )
            check_bvh_fits(
                "host",
                spheres.shape[1],
                host_available_bytes(),
                bvh_mod.BUILD_SPHERE_BYTES,
                width * height * HOST_PIXEL_BYTES,
            )
        self.spheres = spheres
        self.width, self.height = width, height
        self.count = spheres.shape[1]
        # a frame's launches with their arguments converted once: numba-cuda's
        # conversion of a BVH kernel's arrays, every launch, fell inside the
        # kernel's timed span (cuda.launch;
        # docs/startup.md#a-launchs-arguments-converted-once-leases-y3-and-y4)
        self._launches = Launches(64)
        self.d_spheres = cuda.to_device(spheres if self.count else np.zeros((7, 1), np.float32))
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
            self._kernel = _whitted_kernel
            if self.schedule == "wavefront":
                self._wavefront = Wavefront(width, height, shading.depth, options.wave_grid)
            if self.accel == "bvh":
                self._build(self.count)
                self.walk = "ray"
            else:  # brute force: a tree of no node
                self.d_nodes = cuda.device_array((0, NODE_FLOATS), np.float32)
                self.d_links = cuda.device_array((0, NODE_FLOATS), np.int32)
                self.d_nodes64 = self.d_nodes.view(np.float64)
                self.d_sphere_rows = cuda.device_array((1, 2), np.float64)  # read by no walk: there is no tree
                self.d_ordered = cuda.device_array((4, 1), np.float32)
                self.d_order = cuda.device_array(1, np.int32)
            self.d_materials = cuda.to_device(shading.materials if self.count else np.ones((5, 1), np.float32))
            self.d_lights = cuda.to_device(shading.lights)
            self.d_pattern = cuda.to_device(shading.pattern)
            self.d_params = cuda.to_device(shading.params)
            self.d_rays = cuda.to_device(np.zeros(len(KINDS), np.int64))
            self.ray_counts = np.zeros(len(KINDS), np.int64)
        elif self.accel == "bvh":
            self._build(self.count)
            self.walk = choose_walk(self._rows_walked()) if walk is None else walk
            self._kernel = _bvh_packet_kernel if self.walk == "packet" else _bvh_kernel
            if options.block is None:
                self.block = DEFAULT_BLOCK[self.walk]
        elif self.kernel == "fast":
            self._kernel = fast_kernel(self.rays, self.staged, self.trip)
            self.d_relative = cuda.device_array((4, max(self.count, 1)), dtype=np.float32)
        else:
            self._kernel = _constant_kernel(self.count) if self.constant_count else _render_kernel
        self.grid = (math.ceil(width / self.block[0]), math.ceil(height / (self.block[1] * self.rays)))
        self._rows = None  # the rows the last launch traced, None for all

    def _build(self, count: int) -> None:
        """The BVH of the first `count` spheres, on the device: built on the
        host and uploaded, or built on the GPU (its arrays kept for the next
        build of as many spheres). build_s is the build alone: on the host
        without the upload (a copy like the spheres'), on the GPU up to the
        tree ready to walk."""
        if self.build == "gpu":
            if self._builder is None or self._builder.n != count:
                self._builder = (
                    cuda_build.Builder(count, quality=self.options.quality, treelet_passes=self.options.treelet_passes)
                    if count >= 2
                    else None
                )
            self.bvh = cuda_build.build(self.spheres[:, :count], self.d_spheres, self._builder)
            # the fresh tree's SAH cost: what update()'s refits are held to
            self._fresh_cost = self._builder.read_cost() if self.bvh.built_on == "gpu" else None
        else:
            self.bvh = cuda_build.upload(bvh_mod.build(self.spheres[:, :count], device="cuda"))
        self._launches.clear()  # they hold the old tree's arrays
        self.build_s = self.bvh.build_s
        self.d_nodes, self.d_links = self.bvh.nodes, self.bvh.links  # the same bytes: one row holds both
        self.d_nodes64 = self.d_nodes.view(np.float64)  # the same again, as the wavefront reads a row
        self.d_ordered, self.d_order = self.bvh.ordered, self.bvh.order
        self._sphere_rows()

    def _sphere_rows(self) -> None:
        """The ordered spheres a row each, as the wavefront's walks read them
        (wavefront.sphere_rows), after each build or refit of the tree; None
        where no wavefront walks it."""
        self.d_sphere_rows = sphere_rows(self.d_ordered) if self._wavefront is not None else None

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
        tree ready to walk."""
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
                launch(_prepare_kernel, max(1, math.ceil(count / 256)), 256, self.d_basis, self.d_spheres, count,
                       self.d_relative)  # fmt: skip
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
