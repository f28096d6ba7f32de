"""The CUDA kernels: raybench.kernels compiled as CUDA device functions
(kernels.make), and the kernels that spread a frame's pixels over threads:
the thesis's pixel programs through the BVH (a ray a thread, or a warp's
rays as packets), brute force's simple and fast kernels, and Whitted's pixel
program (the wavefront's stages are backends/cuda/wavefront.py's)."""

from __future__ import annotations

import functools

import numpy as np
from numba import cuda

from ... import compiled, kernels
from ...kernels.constants import FAR, ZERO
from ...kernels.primitives import sphere
from ...kernels.whitted import RAY_FLOATS, RAY_INTS, RAY_STACK
from ...layout import NODE_BYTES, RADIUS, STACK
from ..options import RAYS_PER_THREAD, STAGED, TRIP

# The walk by default: packets once the tree outgrows the L1 cache (256 KiB
# an SM on the GPUs measured): the packets cost more node visits than a ray
# at a time and save fetches, so they pay once the tree is fetched from L2;
# measured, the two crossed as the tree outgrew L1
# (docs/notes/bvh-walk.md#packets-of-rays-on-the-gpu-kept).
PACKET_TREE_BYTES = 256 * 1024


def choose_walk(nodes: int) -> str:
    """The walk for a tree of `nodes` rows, when the user did not choose."""
    return "packet" if nodes * NODE_BYTES > PACKET_TREE_BYTES else "ray"


@cuda.jit(device=True)
def _any_in_block(p):
    """Whether p holds in any thread of the block: the packet walk's vote
    (a barrier, which takes an int32 predicate on a GPU)."""
    return cuda.syncthreads_or(np.int32(p)) != 0


def in_tree_order(primitive) -> bool:
    """Whether cuda traces a kind through the tree with its scene's buffer
    put in the tree's order, as the leaves and as what the shading reads
    (kernels.make's positions): every kind but the sphere, whose buffer is
    updated in place as the spheres move and whose leaf is four of its seven
    rows. A mesh's triangles are then on the device once, not twice
    (docs/triangles.md#memory)."""
    return primitive is not sphere


# The voted walk is forced inline into its kernel, where its loop was
# written before it was traverse's, so that the kernel's stack stays its
# own local memory: the form measured as fast as that kernel (inlining
# alone was not what the earlier forms lacked:
# docs/notes/one-source.md#one-walk-for-a-ray-and-a-packet).
# Made for a primitive, the sphere's at import; compiled.rebound compiles
# this module's kernels again for another kind (backends/cuda/kinds.py).
@functools.cache
def _made(primitive=sphere):
    """kernels.make for this backend, for one kind of primitive."""
    return kernels.make(
        cuda.jit(device=True),
        vote=_any_in_block,
        voted_jit=compiled.cuda_device(forceinline=True),
        primitive=primitive,
        positions=in_tree_order(primitive),
    )


_k = _made()
# module globals, which is how kernels can see them
_render_pixel, _primary_ray, _store_pixel, _store_walked = (
    _k.render_pixel,
    _k.primary_ray,
    _k.store_pixel,
    _k.store_walked,
)
_prepare_one, _may_hit, _along, _intersect_relative = (
    _k.prepare,
    _k.prim.may_hit,
    _k.prim.along,
    _k.prim.intersect_relative,
)
_render_pixel_bvh = _k.render_pixel_bvh
_packet_walk = _k.packet_walk

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


@compiled.cuda_jit()
def _bvh_packet_kernel(width, height, first, end, basis, nodes, links, ordered, order, spheres, image, hits):
    """The BVH walk with the block's rays as one packet (traverse's walk,
    voted by the block's barriers, _any_in_block), the children taken in
    the order of their centres along the block's central ray. The barriers
    are in numba's CUDA simulator too, so the tests run this very code; in
    a one-warp block (8x4, the default) they cost what warp votes do
    (measured). Every thread takes part in every vote: those off the image
    trace a copy of its last row or column, unstored."""
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
    stack_row = cuda.local.array(STACK, np.int32)  # the same in every thread
    stack_t = cuda.local.array(STACK, np.float32)  # where this thread's ray enters the node
    hit, _t, hit_d = _packet_walk(basis[0, 0], basis[0, 1], basis[0, 2], dx, dy, dz, cdx, cdy, cdz, FAR, False,
                                  False, -1, False, nodes, links, ordered, order, stack_row, stack_t)  # fmt: skip
    if x < width and y < end:
        _store_walked(x, y, hit, hit_d, spheres, order, image, hits)


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
        # for Python's negative indexing (step 4 of docs/notes/floors.md#each-version-against-the-floor).
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
                # (docs/notes/floors.md#each-version-against-the-floor has what each
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
                # The exact test on the staged EO and the sphere's radius, not
                # the primitive's hit_from on its row seen from the eye (as the
                # cpu's fast kernels): that reads four words a sphere where this
                # reads one, which slowed small scenes
                # (docs/notes/floors.md#the-fast-kernels-exact-test)
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
