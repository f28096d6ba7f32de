"""CPU backend: rows spread over threads, each running the compiled kernel
with the GIL released.

Brute force (accel "none") cuts the image into equal bands of rows, one per
thread: the thesis's own scheme ("divided up into eight threads, which each
process an equal amount of pixels"), any thread count from 1 to one per row.
Its two kernels: "simple", the thesis's loop a pixel at a time, and "fast",
which runs a SIMD cull test over groups of spheres before the exact test
(same pixels). With the BVH (accel "bvh", the default) the rays of a 16x8
tile of pixels walk the tree together (_bvh_packets), so each node's boxes
are tested against all of them with SIMD; a pixel's cost follows how many nodes
its ray crosses, which varies across the picture, so equal bands would
leave threads idle: the threads instead pull small chunks of rows from a
shared iterator until none are left.

Ctrl-C mid-frame: the bands run on the pool's threads (one thread's too),
while the main thread only waits, and so takes the signal at once; it then
sets the tracer's stop flag, which every kernel reads before each row (or
row of packets), and waits for the kernels to return: a frame of minutes
stops within a row's time, at no measured cost to a frame
(docs/faults.md#ctrl-c-mid-frame).

fastmath stays off: the float32 arithmetic is then exactly IEEE, so the CPU image
is bit-identical to the CUDA kernel run under numba's simulator, and the tests
can hold the two to equality rather than to a tolerance.
"""

from __future__ import annotations

import functools
import time
from concurrent import futures
from concurrent.futures import ThreadPoolExecutor

import numba
import numpy as np

from .. import bvh as bvh_mod
from .. import compiled, kernels
from ..host import host_available_bytes, usable_cores
from ..kernels import whitted as whitted_mod
from ..kernels.constants import FAR, ZERO
from ..layout import (
    BLUE,
    CHILD_BOX,
    COUNT,
    GREEN,
    INNER,
    NODE_FLOATS,
    PAD,
    RADIUS,
    RED,
    REF,
    STACK,
    W_COUNT,
    W_HI,
    W_LO,
    W_REF,
    WIDE_STACK,
    WIDTH,
)
from ..lighting import MAX_LIGHTS, Shading
from .contract import TracerBase, check_moved
from .limits import (
    HOST_PIXEL_BYTES,
    check_bvh_fits,
    check_count,
    check_fits,
    check_rows,
)
from .options import CpuOptions, checked

# A hit's shadow rays to one light, traced together: its samples,
# LANES at a time, walk the 4-wide tree as one packet of rays from one origin
# (the hit point), any hit, each ray with its own length (the distance to
# its sample) and done once blocked, the packet once all are
# (_shadow_packet). The pixel program, written once, calls them through
# whitted.build's `shadows` pair: cast traces a light's samples before its
# loop over them, blocked reads the answer. LANES: the loops over a packet's
# rays become SIMD only from 16 (LLVM's loop vectoriser leaves loops of fewer
# iterations scalar: tried 4 and 8, also with the rays' bits ORed as
# _wide_mask does), so a light of 4 samples fills a quarter of the lanes;
# they cost little next to four rays' scalar walks
# (docs/whitted.md#cpu-shadow-rays-as-packets-issue-27).
LANES = 16
_DEAD = np.float32(-np.inf)  # a lane's length once blocked or where no ray is cast: no box is entered
# The last blockers' slots (_last_blocker), a pair of the sphere the rays
# leave and the light to one slot: prime, so that neighbouring spheres'
# pairs spread over all of them.
BLOCKER_SLOTS = 251


def _packet_shadows(jit, find, toward):
    """whitted.build's `shadows` for the CPU's packets: (cast, blocked).
    tree: the packets program's tuple (the _T_ indices below: the trees,
    then the thread's own scratch, _whitted_rows_packets)."""

    @jit
    def cast(px, py, pz, nx, ny, nz, light, samples, share, own, own_inside, spheres, count, lights, pattern, tree,
             stack_row, stack_t):  # fmt: skip
        """Bit s set where sample s's ray is blocked; 0 for samples whose
        ray is not cast (toward's facing 0)."""
        rays = tree[_T_RAYS]
        blockers = tree[_T_BLOCKERS]
        slot = (own * MAX_LIGHTS + light) % BLOCKER_SLOTS
        batch = np.int64(0)
        for first in range(0, samples, LANES):
            live = np.int64(0)
            lead = -1
            for k in range(LANES):
                s = first + k
                rays[_LEN, k] = _DEAD
                if s < samples:
                    lx, ly, lz, dist, facing, _r, _g, _b = toward(px, py, pz, nx, ny, nz, light, s, share, lights,
                                                                  pattern)  # fmt: skip
                    if facing > ZERO:
                        rays[_DX, k] = lx
                        rays[_DY, k] = ly
                        rays[_DZ, k] = lz
                        rays[_LEN, k] = dist
                        live |= np.int64(1) << np.int64(k)
                        if lead < 0:
                            lead = k
            if lead < 0:
                continue
            if _last_blocker(px, py, pz, rays, tree[2], tree[3], blockers[slot], own, own_inside) == _DEAD:
                batch |= live << np.int64(first)  # every ray blocked by the sphere that blocked the last
                continue
            for k in range(LANES):  # lanes without a ray follow the first live one: the spread stays tight
                if not (live >> np.int64(k)) & np.int64(1):
                    rays[_DX, k] = rays[_DX, lead]
                    rays[_DY, k] = rays[_DY, lead]
                    rays[_DZ, k] = rays[_DZ, lead]
            batch |= _shadow_packet(px, py, pz, rays, tree[_T_SPREAD], tree[_T_STACK], tree[_T_WIDE],
                                    tree[_T_WIDE_LINKS], tree[2], tree[3], own, own_inside, live, blockers,
                                    slot) << np.int64(first)  # fmt: skip
        return batch

    @jit
    def blocked(batch, s, px, py, pz, lx, ly, lz, dist, own, own_inside, spheres, count, tree, stack_row, stack_t):
        return (batch >> np.int64(s)) & np.int64(1) != 0

    return cast, blocked


@numba.njit(inline="always", error_model="numpy")
def _ray_box(w, c, lx, ly, lz, hx, hy, hz, ix, iy, iz, closest):
    """traverse.slab's test of one ray on child box c of wide row w (lx =
    origin + margin, hx = origin - margin: the box grown by the margin, as
    traverse.axis_setup's, which gives them times 1/d for the GPU's fused
    multiply-add; a CPU without it gains nothing from that form): (whether
    it enters no farther than closest, where it enters)."""
    a0 = (w[_U(LO_X) + c] - lx) * ix
    a1 = (w[_U(LO_Y) + c] - ly) * iy
    a2 = (w[_U(LO_Z) + c] - lz) * iz
    b0 = (w[_U(HI_X) + c] - hx) * ix
    b1 = (w[_U(HI_Y) + c] - hy) * iy
    b2 = (w[_U(HI_Z) + c] - hz) * iz
    near = max(min(a0, b0), max(min(a1, b1), min(a2, b2)))
    far = min(max(a0, b0), min(max(a1, b1), max(a2, b2)))
    return (near <= far) & (far > ZERO) & (near <= closest), near


@numba.njit(inline="always", error_model="numpy")
def _ray_boxes(wide, row, lx, ly, lz, hx, hy, hz, ix, iy, iz, closest):
    """_ray_box on a wide node's four boxes, written out as four like
    computations that LLVM's SLP vectoriser can put in one register: (a bit
    set for each box entered, the four entry distances)."""
    w = wide[row]
    k0, n0 = _ray_box(w, _U(0), lx, ly, lz, hx, hy, hz, ix, iy, iz, closest)
    k1, n1 = _ray_box(w, _U(1), lx, ly, lz, hx, hy, hz, ix, iy, iz, closest)
    k2, n2 = _ray_box(w, _U(2), lx, ly, lz, hx, hy, hz, ix, iy, iz, closest)
    k3, n3 = _ray_box(w, _U(3), lx, ly, lz, hx, hy, hz, ix, iy, iz, closest)
    mask = np.int64(k0) | (np.int64(k1) << 1) | (np.int64(k2) << 2) | (np.int64(k3) << 3)
    return mask, (n0, n1, n2, n3)


@numba.njit(inline="always", error_model="numpy")
def _walk_wide(ox, oy, oz, dx, dy, dz, t_max, any_hit, own, own_inside, wide, wide_links, ordered, order, s_ref,
               s_count, s_t):  # fmt: skip
    """traverse.walk's answer for one Whitted ray (its `ahead` test, the
    sphere `own` skipped or met at its far root) through the 4-wide tree: a
    node's four boxes tested at once (_ray_boxes), the children it enters
    pushed farthest first with where the ray enters each, popped nearest
    first and skipped once a hit is nearer. The nearest sphere with 0 < t <
    t_max, ties to the smaller original index, or with any_hit the first
    found: the same (index, t, d) as the binary tree's walk, whose boxes
    are the same padded ones, as no order of visiting changes which sphere
    is nearest. s_ref, s_count, s_t: the stack (layout.WIDE_STACK)."""
    ix, iy, iz = _inverse(dx), _inverse(dy), _inverse(dz)
    margin = (abs(ox) + abs(oy) + abs(oz)) * PAD
    lx, ly, lz = ox + margin, oy + margin, oz + margin
    hx, hy, hz = ox - margin, oy - margin, oz - margin
    closest = t_max
    hit = np.int64(-1)
    hit_d = ZERO
    s_ref[0] = 0
    s_count[0] = INNER
    s_t[0] = ZERO
    top = 1
    while top > 0:
        top -= 1
        if s_t[top] > closest:
            continue
        node = s_ref[top]
        if s_count[top] != INNER:
            for j in range(_U(node), _U(node + s_count[top])):
                original = order[j]
                if original == own and not own_inside:
                    continue
                t, d = _intersect_ahead_v(ordered[0, j] - ox, ordered[1, j] - oy, ordered[2, j] - oz, ordered[3, j],
                                          dx, dy, dz, original == own)  # fmt: skip
                if t > ZERO and (t < closest or (t == closest and original < hit)):
                    closest = t
                    hit = np.int64(original)
                    hit_d = d
            if any_hit and hit >= 0:
                return hit, closest, hit_d
            continue
        mask, nears = _ray_boxes(wide, node, lx, ly, lz, hx, hy, hz, ix, iy, iz, closest)
        base = top
        for c in range(WIDTH):
            if not (mask >> c) & 1:
                continue
            near = nears[c]
            j = top  # insertion among this node's children, the nearest on top
            while j > base and s_t[j - 1] < near:
                s_ref[j] = s_ref[j - 1]
                s_count[j] = s_count[j - 1]
                s_t[j] = s_t[j - 1]
                j -= 1
            s_ref[j] = wide_links[node, W_REF + c]
            s_count[j] = wide_links[node, W_COUNT + c]
            s_t[j] = near
            top += 1
    return hit, closest, hit_d


# The packets program's tree tuple (_whitted_rows_packets): the binary
# tree's four arrays, the wide tree's two, the shadow packets' scratch
# (_packet_shadows), the tile's primary hits (_tile_primaries), the lane of
# the pixel being shaded, the single-ray walk's stack, and the shadow rays'
# last blockers.
_T_WIDE, _T_WIDE_LINKS, _T_RAYS, _T_SPREAD, _T_STACK = 4, 5, 6, 7, 8
_T_HIT, _T_CLOSEST, _T_HIT_D, _T_LANE, _T_S_REF, _T_S_COUNT, _T_S_T = 9, 10, 11, 12, 13, 14, 15
_T_BLOCKERS = 16  # the last blockers (rows of `ordered`, -1 for none) by sphere and light: _last_blocker


@numba.njit(inline="always")
def _search_wide(ox, oy, oz, dx, dy, dz, t_max, any_hit, own, own_inside, spheres, count, tree, stack_row, stack_t):
    """The packets program's search (trace.search_tree's signature): a
    primary ray (the one ray that leaves no sphere, own < 0) reads its hit
    from its tile's packet, walked before the tile's pixels are shaded; the
    reflected and refracted rays walk the 4-wide tree alone (_walk_wide)."""
    if own < 0:
        k = tree[_T_LANE][0]
        return np.int64(tree[_T_HIT][k]), tree[_T_CLOSEST][k], tree[_T_HIT_D][k]
    return _walk_wide(ox, oy, oz, dx, dy, dz, t_max, any_hit, own, own_inside, tree[_T_WIDE], tree[_T_WIDE_LINKS],
                      tree[2], tree[3], tree[_T_S_REF], tree[_T_S_COUNT], tree[_T_S_T])  # fmt: skip


# find, the one call of the Whitted programs through the binary tree and by
# brute force, is compiled without the runtime's reference counting
# (_nrt=False; _whitted_tiles says why): it allocates nothing and keeps no
# array. The packets program inlines its find (trace.build).
_k = kernels.build(
    numba.njit(inline="always"),
    call=numba.njit(nogil=True, _nrt=False),
    shadows=_packet_shadows,
    packets_search=_search_wide,
)
# module globals, which is how jitted code can see them
_render_pixel, _primary_ray, _store_pixel = _k.render_pixel, _k.primary_ray, _k.store_pixel
_prepare_one, _may_hit, _intersect_relative = _k.prepare, _k.may_hit, _k.intersect_relative
# The BVH walk's own build of the same functions, with NumPy's error model:
# float division then has no check for a zero divisor (none can occur: the
# divisors are the image size, a ray's length, a radius, a direction
# component raised to at least TINY), so the result is the same IEEE
# quotient, and LLVM can make the loops over a packet's rays SIMD, which the
# check's branch prevents (vdivps, vsqrtps in the assembly).
_kb = kernels.build(numba.njit(inline="always", error_model="numpy"))
_primary_ray_v, _intersect_relative_v, _inverse, _centre = (
    _kb.primary_ray,
    _kb.intersect_relative,
    _kb.inverse,
    _kb.centre_along,
)
_intersect_ahead_v = _kb.intersect_ahead
_shade_hit_v, _shade_miss_v, _to_byte_v = _kb.shade_hit, _kb.shade_miss, _kb.to_byte

# The cull loops index the spheres with unsigned integers: a signed index
# carries Python's negative-index wraparound, a select per lane that LLVM
# turns into gathers, which halved the cull's speed (step 5 of
# docs/floors.md#each-version-against-the-floor). The CUDA fast kernel does the
# same for the same reason.
_U = np.uint64
# Spheres per cull group in the fast kernels: a group's cull test is one
# loop that LLVM turns into SIMD. 32 measured fastest: 16 and 64 were slower,
# and 48 did not vectorise (steps 3 and 4 of docs/floors.md#each-version-against-the-floor).
GROUP = 32
# Rays side by side in the AVX-512 kernel: one 16-lane register of float32.
WIDE = 16


@compiled.njit(nogil=True)
def _render_band(first_row, end_row, width, height, basis, spheres, count, image, hits, stop):
    for y in range(first_row, end_row):
        if stop[0]:
            return
        for x in range(width):
            _render_pixel(x, y, width, height, basis, spheres, count, image, hits)


@functools.cache
def _constant_band(count: int):
    """_render_band with the sphere count frozen into the code (a compile-time
    constant, as in the thesis's tests 1 to 6); one compilation per count."""

    @numba.njit(nogil=True)
    def render_band(first_row, end_row, width, height, basis, spheres, _count, image, hits, stop):
        for y in range(first_row, end_row):
            if stop[0]:
                return
            for x in range(width):
                _render_pixel(x, y, width, height, basis, spheres, count, image, hits)

    return render_band


@compiled.njit(nogil=True)
def _prepare(basis, spheres, count, relative):
    for i in range(count):
        _prepare_one(i, basis, spheres, relative)


@compiled.njit(nogil=True)
def _pairs_band(first_row, end_row, width, height, basis, spheres, relative, count, image, hits, stop):
    """The fast kernel for AVX2 and narrower: the rows of a band two pixels at
    a time, the spheres GROUP at a time. The cull test of a whole group on
    both rays is one SIMD loop across the spheres (each sphere's EO loaded
    once for two rays), and only a group it cannot rule out is walked again,
    sphere by sphere, with the exact test. Same arithmetic, same order of
    spheres, same pixels as _render_band."""
    ex, ey, ez, es = relative[0], relative[1], relative[2], relative[3]
    radius = spheres[RADIUS]
    for y in range(first_row, end_row):
        if stop[0]:
            return
        for x in range(0, width, 2):
            x1 = min(x + 1, width - 1)  # an odd width traces its last pixel twice, stores it once
            ax, ay, az = _primary_ray(x, y, width, height, basis)
            bx, by, bz = _primary_ray(x1, y, width, height, basis)
            a_closest, a_hit, a_d = FAR, -1, ZERO
            b_closest, b_hit, b_d = FAR, -1, ZERO
            for first in range(0, count, GROUP):
                end = min(first + GROUP, count)
                maybe = False
                for i in range(_U(first), _U(end)):
                    maybe |= _may_hit(ex[i], ey[i], ez[i], es[i], ax, ay, az) | _may_hit(
                        ex[i], ey[i], ez[i], es[i], bx, by, bz
                    )
                if maybe:
                    for i in range(first, end):
                        if _may_hit(ex[i], ey[i], ez[i], es[i], ax, ay, az):
                            t, d = _intersect_relative(ex[i], ey[i], ez[i], radius[i], ax, ay, az)
                            if t < a_closest and t > ZERO:
                                a_closest, a_hit, a_d = t, i, d
                        if _may_hit(ex[i], ey[i], ez[i], es[i], bx, by, bz):
                            t, d = _intersect_relative(ex[i], ey[i], ez[i], radius[i], bx, by, bz)
                            if t < b_closest and t > ZERO:
                                b_closest, b_hit, b_d = t, i, d
            _store_pixel(x, y, a_hit, a_d, spheres, image, hits)
            if x1 > x:
                _store_pixel(x1, y, b_hit, b_d, spheres, image, hits)


@compiled.njit(nogil=True)
def _wide_band(first_row, end_row, width, height, basis, spheres, relative, count, image, hits, stop):
    """The fast kernel for AVX-512: WIDE pixels of a row side by side, so the
    cull test of each sphere is one SIMD compare across the rays; a group of
    GROUP spheres is walked again with the exact test only where some ray
    may hit one of them. Same arithmetic, same order, same pixels."""
    ex, ey, ez, es = relative[0], relative[1], relative[2], relative[3]
    radius = spheres[RADIUS]
    dx = np.empty(WIDE, np.float32)
    dy = np.empty(WIDE, np.float32)
    dz = np.empty(WIDE, np.float32)
    closest = np.empty(WIDE, np.float32)
    hit = np.empty(WIDE, np.int64)
    hit_d = np.empty(WIDE, np.float32)
    for y in range(first_row, end_row):
        if stop[0]:
            return
        for x in range(0, width, WIDE):
            for k in range(WIDE):  # pixels past the edge trace a copy of the last one, unstored
                dx[k], dy[k], dz[k] = _primary_ray(min(x + k, width - 1), y, width, height, basis)
                closest[k], hit[k], hit_d[k] = FAR, -1, ZERO
            for first in range(0, count, GROUP):
                end = min(first + GROUP, count)
                maybe = False
                for i in range(_U(first), _U(end)):
                    for k in range(WIDE):
                        maybe |= _may_hit(ex[i], ey[i], ez[i], es[i], dx[k], dy[k], dz[k])
                if maybe:
                    for i in range(first, end):
                        # Most spheres of a group that passed are still missed by
                        # all 16 rays: one SIMD test across the rays first keeps
                        # the scalar loop for the spheres some ray may hit
                        # (step 5 of docs/floors.md#each-version-against-the-floor).
                        some = False
                        for k in range(WIDE):
                            some |= _may_hit(ex[i], ey[i], ez[i], es[i], dx[k], dy[k], dz[k])
                        if not some:
                            continue
                        for k in range(WIDE):
                            if _may_hit(ex[i], ey[i], ez[i], es[i], dx[k], dy[k], dz[k]):
                                t, d = _intersect_relative(ex[i], ey[i], ez[i], radius[i], dx[k], dy[k], dz[k])
                                if t < closest[k] and t > ZERO:
                                    closest[k], hit[k], hit_d[k] = t, i, d
            for k in range(min(WIDE, width - x)):
                _store_pixel(x + k, y, hit[k], hit_d[k], spheres, image, hits)


def _has_avx512() -> bool:
    """Whether the CPU Numba compiles for has 16-lane float32 registers."""
    try:
        from llvmlite import binding

        return bool(binding.get_host_cpu_features().get("avx512f", False))
    except Exception:  # noqa: BLE001 - an llvmlite without the query: the kernel that suits every CPU
        return False


# Which loop vectorises best depends on the register width: with AVX-512 the
# wide kernel (16 rays side by side) took half the pairs kernel's time, with
# AVX2 the pairs kernel was the faster (step 4 of
# docs/floors.md#each-version-against-the-floor).
_fast_band = _wide_band if _has_avx512() else _pairs_band


# Rays walked through the BVH together by _bvh_packets: a 16x8 tile of
# pixels, eight AVX-512 or sixteen AVX2 registers of float32 per ray
# component. Once the walk stopped reducing the packet's entry distances
# (the children ordered along the middle ray instead), larger packets paid:
# of 4x4 to 32x8, 16x8 was the fastest, ahead of 8x4, the shape before; 16x16
# is as fast on one core and slower at 1,000 spheres on two threads
# (docs/bvh-walk.md#measured-cpu-only-machine-amd-epyc-2-vcpus-shared).
PACKET_W, PACKET_H = 16, 8
PACKET = PACKET_W * PACKET_H
# The wide rows' plane columns by axis (layout.W_LO, W_HI), as plain ints: read
# as compile-time constants, as literal offsets were.
LO_X, LO_Y, LO_Z = W_LO
HI_X, HI_Y, HI_Z = W_HI
_MIDDLE = (PACKET_H // 2) * PACKET_W + PACKET_W // 2


@numba.njit(inline="always")
def _spread(ix, iy, iz, spread):
    """spread[:6]: the packet's range of inverse directions on each axis (x
    low, x high, y low, ...); spread[6]: its farthest closest hit, FAR."""
    for a, inv in enumerate((ix, iy, iz)):
        lo = hi = inv[0]
        for k in range(1, PACKET):
            lo = min(lo, inv[k])
            hi = max(hi, inv[k])
        spread[2 * a] = lo
        spread[2 * a + 1] = hi
    spread[6] = FAR


@numba.njit(inline="always", error_model="numpy")
def _missed_by_all(lx, ly, lz, hx, hy, hz, spread):
    """Whether no ray of the packet enters the box (planes relative to the
    rays' origin) nearer than its closest hit, by one test for them all
    (interval arithmetic, as in Wald, Boulos and Shirley 2007): each ray's
    inverse direction lies within spread's ranges, so its entry is no nearer,
    and its exit no farther, than bounds taken at the ranges' ends
    (min(l * i, h * i) is concave in i, max(l * i, h * i) convex). Rounding
    is monotonic, so the bounds hold for the float32 products a ray's own
    box test computes: True only where that test fails for every ray."""
    x0, x1, y0, y1, z0, z1 = spread[0], spread[1], spread[2], spread[3], spread[4], spread[5]
    near = max(
        min(min(lx * x0, hx * x0), min(lx * x1, hx * x1)),
        max(min(min(ly * y0, hy * y0), min(ly * y1, hy * y1)), min(min(lz * z0, hz * z0), min(lz * z1, hz * z1))),
    )
    far = min(
        max(max(lx * x0, hx * x0), max(lx * x1, hx * x1)),
        min(max(max(ly * y0, hy * y0), max(ly * y1, hy * y1)), max(max(lz * z0, hz * z0), max(lz * z1, hz * z1))),
    )
    # one branch where it is used, not three (`or` would branch on each, and
    # mispredicted they cost 10-13% of the frame)
    return (near > far) | (far <= ZERO) | (near > spread[6])


@numba.njit(inline="always", error_model="numpy")
def _packet_box(nodes, row, col, ox, oy, oz, margin, ix, iy, iz, spread, closest):
    """Whether any ray of the packet enters the child box (grown by margin,
    as in kernels.traverse) nearer than its closest hit so far. The rays
    share their origin, so the planes' offsets from it are computed once for
    all. First one test for the whole packet (_missed_by_all): of the boxes
    no ray enters, 42-44% of those tested in the benchmark's scenes, it finds
    90-98%. Then the rays, a row of the packet at a time; the test stops at
    the first row with a ray that enters: most boxes that get this far are
    entered, and by rays of every row. Each row's loop has no branch and no
    float reduction, so LLVM makes it SIMD (without fastmath it vectorises
    neither)."""
    lx = nodes[row, col] - margin - ox
    ly = nodes[row, col + 1] - margin - oy
    lz = nodes[row, col + 2] - margin - oz
    hx = nodes[row, col + 3] + margin - ox
    hy = nodes[row, col + 4] + margin - oy
    hz = nodes[row, col + 5] + margin - oz
    if _missed_by_all(lx, ly, lz, hx, hy, hz, spread):
        return False
    return _rows_enter(lx, ly, lz, hx, hy, hz, ix, iy, iz, closest)


@numba.njit(inline="always", error_model="numpy")
def _rows_enter(lx, ly, lz, hx, hy, hz, ix, iy, iz, closest):
    """Whether any ray of the packet enters the box of planes (lx, ..., hz)
    relative to the rays' origin nearer than its closest hit: the rays a row
    of the packet at a time (SIMD), stopping at the first row with a ray
    that enters (_packet_box)."""
    for first in range(0, PACKET, PACKET_W):
        entered = False
        for k in range(first, first + PACKET_W):
            t1, t2 = lx * ix[k], hx * ix[k]
            t3, t4 = ly * iy[k], hy * iy[k]
            t5, t6 = lz * iz[k], hz * iz[k]
            near = max(min(t1, t2), max(min(t3, t4), min(t5, t6)))
            far = min(max(t1, t2), min(max(t3, t4), max(t5, t6)))
            entered |= (near <= far) & (far > ZERO) & (near <= closest[k])
        if entered:
            return True
    return False


@numba.njit(inline="always", error_model="numpy")
def _packet_leaf(
    ox, oy, oz, margin, dx, dy, dz, ordered, order, first, count, spread, closest, hit, hit_d, closest_bits,
    spread_bits, ahead=False,
):  # fmt: skip
    """The exact test of a leaf's spheres on every ray of the packet: EO as
    intersect_sphere computes it, the walk's tie rule; ahead: Whitted's
    primary rays' test (intersect_ahead for a ray that leaves no sphere, as
    traverse.leaf_test makes it: the far root where the near one is behind,
    a camera inside a sphere). A sphere whose own
    box (as the builder pads it, grown by margin as the walk grows boxes) no
    ray enters is skipped after one test for the packet (_missed_by_all):
    in the benchmark's scenes, 56-74% of the spheres of the leaves the
    packets enter."""
    for j in range(first, first + count):
        cx, cy, cz, r, original = ordered[0, j], ordered[1, j], ordered[2, j], ordered[3, j], order[j]
        pr = r + bvh_mod.sphere_pad(cx, cy, cz, r)
        if _missed_by_all(
            cx - pr - margin - ox,
            cy - pr - margin - oy,
            cz - pr - margin - oz,
            cx + pr + margin - ox,
            cy + pr + margin - oy,
            cz + pr + margin - oz,
            spread,
        ):
            continue
        ex, ey, ez = cx - ox, cy - oy, cz - oz
        for k in range(PACKET):
            if ahead:
                t, d = _intersect_ahead_v(ex, ey, ez, r, dx[k], dy[k], dz[k], False)
            else:
                t, d = _intersect_relative_v(ex, ey, ez, r, dx[k], dy[k], dz[k])
            c = closest[k]
            better = (t > ZERO) & ((t < c) | ((t == c) & (original < hit[k])))
            closest[k] = t if better else c
            hit[k] = original if better else hit[k]
            hit_d[k] = d if better else hit_d[k]
    # spread[6] = the farthest closest hit: closest holds positive float32
    # only, whose bit patterns order as the floats do, so an integer maximum,
    # which LLVM makes SIMD (a float one it would not)
    m = closest_bits[0]
    for k in range(1, PACKET):
        m = max(m, closest_bits[k])
    spread_bits[6] = m


@numba.njit(inline="always", error_model="numpy")
def _colour_packet(x0, y0, spheres, hit, hit_d, rgb, paint):
    """rgb[c, k]: the bytes store_pixel writes for ray k of the packet, for
    every ray at once: first the hit spheres' colours and radii gathered
    (a miss reads sphere 0's and drops them), then shaded in a loop without
    branches (each ray's hit and miss colours both computed, one kept),
    which LLVM makes SIMD. spheres must hold a sphere (Tracer.shaded)."""
    for k in range(PACKET):
        j = max(hit[k], 0)
        paint[0, k] = spheres[RED, j]
        paint[1, k] = spheres[GREEN, j]
        paint[2, k] = spheres[BLUE, j]
        paint[3, k] = spheres[RADIUS, j]
    for k in range(PACKET):
        hr, hg, hb = _shade_hit_v(paint[0, k], paint[1, k], paint[2, k], paint[3, k], hit_d[k])
        mr, mg, mb = _shade_miss_v(np.float32(np.int32(x0 + k % PACKET_W)), np.float32(np.int32(y0 + k // PACKET_W)))
        got = hit[k] >= 0
        rgb[0, k] = _to_byte_v(hr if got else mr)
        rgb[1, k] = _to_byte_v(hg if got else mg)
        rgb[2, k] = _to_byte_v(hb if got else mb)


@numba.njit(inline="always")
def _put_pixel(y, x, k, rgb, hit, image, hits):
    """Store ray k's bytes and hit index at pixel (x, y), each at least 0.
    Unsigned indices (_U), as in the cull loops: a signed one carries
    Python's negative-index wraparound, a shift, a mask and an add for each
    of a pixel's four stores (what they cost:
    docs/embree.md#against-mitsuba-3-on-embree-side-by-side-2-vcpu-machine)."""
    y, x, k = _U(y), _U(x), _U(k)
    image[y, x, _U(0)] = rgb[_U(0), k]
    image[y, x, _U(1)] = rgb[_U(1), k]
    image[y, x, _U(2)] = rgb[_U(2), k]
    hits[y, x] = hit[k]


@numba.njit(inline="always")
def _start_packet(x0, y0, end_row, width, height, basis, dx, dy, dz, ix, iy, iz, closest, hit, hit_d, spread):
    """The packet of rays from pixel (x0, y0): their directions and inverses,
    nothing hit yet, and their spread (_spread). Inlined into each packet
    walk; separate loops, each simple enough for LLVM to make SIMD."""
    for k in range(PACKET):
        # rays off the chunk trace a copy of its last row or column, unstored;
        # a pixel's coordinates as int32 (exact: a side is at most
        # limits.MAX_SIDE), which AVX2 turns into float32 eight at a time,
        # where an int64 takes a scalar conversion each
        # (docs/embree.md#against-mitsuba-3-on-embree-side-by-side-2-vcpu-machine)
        x = np.int32(min(x0 + k % PACKET_W, width - 1))
        y = np.int32(min(y0 + k // PACKET_W, end_row - 1))
        dx[k], dy[k], dz[k] = _primary_ray_v(x, y, width, height, basis)
    for k in range(PACKET):
        ix[k] = _inverse(dx[k])
        iy[k] = _inverse(dy[k])
        iz[k] = _inverse(dz[k])
    for k in range(PACKET):
        closest[k] = FAR
        hit[k] = -1
        hit_d[k] = ZERO
    _spread(ix, iy, iz, spread)


@numba.njit(inline="always")
def _store_packet(x0, y0, end_row, width, spheres, hit, hit_d, rgb, paint, image, hits):
    """The packet's pixels shaded and stored, those inside the frame's rows."""
    _colour_packet(x0, y0, spheres, hit, hit_d, rgb, paint)
    if x0 + PACKET_W <= width and y0 + PACKET_H <= end_row:
        # a whole packet: rows of pixels stored without a test each
        for line in range(PACKET_H):
            for i in range(PACKET_W):
                _put_pixel(y0 + line, x0 + i, line * PACKET_W + i, rgb, hit, image, hits)
    else:
        for k in range(PACKET):
            x = x0 + k % PACKET_W
            y = y0 + k // PACKET_W
            if x < width and y < end_row:
                _put_pixel(y, x, k, rgb, hit, image, hits)


@compiled.njit(nogil=True, error_model="numpy")
def _bvh_packets(first_row, end_row, width, height, basis, nodes, links, ordered, order, spheres, image, hits, stop):
    """The rows first_row..end_row, a PACKET_W x PACKET_H packet of rays at a time: the
    packet walks the tree together, a node entered if any of its rays
    enters it, each box and leaf test run across the packet's rays (loops
    LLVM turns into SIMD). Each ray still gets the nearest sphere of all it
    could hit, ties to the smaller index: the pixels of kernels.traverse's walk, one ray at a time."""
    stack_row = np.empty(STACK, np.int32)
    dx = np.empty(PACKET, np.float32)
    dy = np.empty(PACKET, np.float32)
    dz = np.empty(PACKET, np.float32)
    ix = np.empty(PACKET, np.float32)
    iy = np.empty(PACKET, np.float32)
    iz = np.empty(PACKET, np.float32)
    closest = np.empty(PACKET, np.float32)
    spread = np.empty(7, np.float32)
    closest_bits, spread_bits = closest.view(np.int32), spread.view(np.int32)
    hit = np.empty(PACKET, np.int32)
    hit_d = np.empty(PACKET, np.float32)
    rgb = np.empty((3, PACKET), np.uint8)
    paint = np.empty((4, PACKET), np.float32)
    ox, oy, oz = basis[0, 0], basis[0, 1], basis[0, 2]
    margin = (abs(ox) + abs(oy) + abs(oz)) * PAD
    for y0 in range(first_row, end_row, PACKET_H):
        if stop[0]:
            return
        for x0 in range(0, width, PACKET_W):
            _start_packet(x0, y0, end_row, width, height, basis, dx, dy, dz, ix, iy, iz, closest, hit, hit_d, spread)
            cdx, cdy, cdz = dx[_MIDDLE], dy[_MIDDLE], dz[_MIDDLE]
            row = 0
            top = 0
            while row >= 0:
                a_in = _packet_box(nodes, row, CHILD_BOX[0], ox, oy, oz, margin, ix, iy, iz, spread, closest)
                b_in = _packet_box(nodes, row, CHILD_BOX[1], ox, oy, oz, margin, ix, iy, iz, spread, closest)
                a_ref, b_ref, a_count, b_count = (
                    links[row, REF],
                    links[row, REF + 1],
                    links[row, COUNT],
                    links[row, COUNT + 1],
                )
                # near child first: the one whose box centre lies nearer along
                # the packet's middle ray
                if b_in and (
                    not a_in
                    or _centre(nodes, row, _U(CHILD_BOX[1]), ox, oy, oz, cdx, cdy, cdz)
                    < _centre(nodes, row, _U(CHILD_BOX[0]), ox, oy, oz, cdx, cdy, cdz)
                ):
                    a_in, a_ref, a_count, b_in, b_ref, b_count = b_in, b_ref, b_count, a_in, a_ref, a_count
                row = -1
                if a_in:
                    if a_count == INNER:
                        row = a_ref
                    else:
                        _packet_leaf(
                            ox,
                            oy,
                            oz,
                            margin,
                            dx,
                            dy,
                            dz,
                            ordered,
                            order,
                            a_ref,
                            a_count,
                            spread,
                            closest,
                            hit,
                            hit_d,
                            closest_bits,
                            spread_bits,
                        )
                if b_in:
                    if b_count != INNER:
                        _packet_leaf(
                            ox,
                            oy,
                            oz,
                            margin,
                            dx,
                            dy,
                            dz,
                            ordered,
                            order,
                            b_ref,
                            b_count,
                            spread,
                            closest,
                            hit,
                            hit_d,
                            closest_bits,
                            spread_bits,
                        )
                    elif row < 0:
                        row = b_ref
                    else:
                        stack_row[top] = b_ref
                        top += 1
                if row < 0 and top > 0:
                    top -= 1
                    row = stack_row[top]
            _store_packet(x0, y0, end_row, width, spheres, hit, hit_d, rgb, paint, image, hits)


@numba.njit(inline="always", error_model="numpy")
def _wide_mask(wide, row, ox, oy, oz, margin, spread):
    """The first step of _packet_box for all WIDTH boxes of a wide node at
    once: a bit set for each box that the interval test for the whole
    packet (_missed_by_all's arithmetic) does not rule out. One loop over
    the boxes, without branches, on planes stored side by side (layout.W_LO,
    W_HI), that only reads memory and ORs the bits together: LLVM makes it
    SIMD, the four boxes in one register (vminps, vmaxps on xmm). Storing
    the planes or the outcomes to arrays in the loop kept it scalar (LLVM
    will not check a loop of 4 for overlapping arrays at run time)."""
    x0, x1, y0, y1, z0, z1, reach = spread[0], spread[1], spread[2], spread[3], spread[4], spread[5], spread[6]
    w = wide[row]
    mask = 0
    for c in range(_U(WIDTH)):
        lx = w[_U(LO_X) + c] - margin - ox
        ly = w[_U(LO_Y) + c] - margin - oy
        lz = w[_U(LO_Z) + c] - margin - oz
        hx = w[_U(HI_X) + c] + margin - ox
        hy = w[_U(HI_Y) + c] + margin - oy
        hz = w[_U(HI_Z) + c] + margin - oz
        near = max(
            min(min(lx * x0, hx * x0), min(lx * x1, hx * x1)),
            max(
                min(min(ly * y0, hy * y0), min(ly * y1, hy * y1)),
                min(min(lz * z0, hz * z0), min(lz * z1, hz * z1)),
            ),
        )
        far = min(
            max(max(lx * x0, hx * x0), max(lx * x1, hx * x1)),
            min(
                max(max(ly * y0, hy * y0), max(ly * y1, hy * y1)),
                max(max(lz * z0, hz * z0), max(lz * z1, hz * z1)),
            ),
        )
        kept = (near <= far) & (far > ZERO) & (near <= reach)
        mask |= np.int64(kept) << np.int64(c)
    return mask


@numba.njit(inline="always", error_model="numpy")
def _wide_planes(wide, row, c, ox, oy, oz, margin):
    """The planes of child c of wide row `row`, its box grown by margin (as
    in kernels.traverse), relative to the packet's shared origin: (lx, ly,
    lz, hx, hy, hz), the packets' box tests' arguments (_rows_enter,
    _lanes_enter)."""
    return (
        wide[row, LO_X + c] - margin - ox,
        wide[row, LO_Y + c] - margin - oy,
        wide[row, LO_Z + c] - margin - oz,
        wide[row, HI_X + c] + margin - ox,
        wide[row, HI_Y + c] + margin - oy,
        wide[row, HI_Z + c] + margin - oz,
    )


@numba.njit(inline="always", error_model="numpy")
def _packet_walk_wide(wide, wide_links, ordered, order, ox, oy, oz, margin, dx, dy, dz, ix, iy, iz, closest, hit,
                      hit_d, spread, closest_bits, spread_bits, stack_row, stack_count, along, chosen,
                      ahead):  # fmt: skip
    """The walk of _bvh_packets_wide's packet (started by _start_packet):
    closest, hit and hit_d of every ray; ahead: _packet_leaf's, for
    Whitted's primary rays. A wide node's four boxes go through the
    packet's interval test together (_wide_mask), then each box it leaves
    through the rays' own test (_rows_enter); the entered children are
    visited nearest first along the packet's middle ray, leaves at once,
    the nearest inner child next and the others pushed."""
    cdx, cdy, cdz = dx[_MIDDLE], dy[_MIDDLE], dz[_MIDDLE]
    row = 0
    top = 0
    while row >= 0:
        mask = _wide_mask(wide, row, ox, oy, oz, margin, spread)
        entered = 0
        for c in range(WIDTH):
            if not (mask >> c) & 1:
                continue
            lx, ly, lz, hx, hy, hz = _wide_planes(wide, row, c, ox, oy, oz, margin)
            if not _rows_enter(lx, ly, lz, hx, hy, hz, ix, iy, iz, closest):
                continue
            # where the box's centre lies along the middle ray: insertion
            # into chosen[:entered], nearest first
            along[c] = (lx + hx) * cdx + (ly + hy) * cdy + (lz + hz) * cdz
            j = entered
            while j > 0 and along[chosen[j - 1]] > along[c]:
                chosen[j] = chosen[j - 1]
                j -= 1
            chosen[j] = c
            entered += 1
        # nearest first: leaves up to the nearest inner child tested
        # now, that child walked next, everything farther pushed (the
        # farthest first), leaves too, so that a near inner child's
        # hits can rule out a farther leaf's spheres
        node = row
        row = -1
        for j in range(entered):
            c = chosen[j]
            ref, count = wide_links[node, W_REF + c], wide_links[node, W_COUNT + c]
            if row < 0 and count != INNER:
                _packet_leaf(ox, oy, oz, margin, dx, dy, dz, ordered, order, ref, count, spread, closest,
                             hit, hit_d, closest_bits, spread_bits, ahead)  # fmt: skip
            elif row < 0:
                row = ref
                for i in range(entered - 1, j, -1):
                    stack_row[top] = wide_links[node, W_REF + chosen[i]]
                    stack_count[top] = wide_links[node, W_COUNT + chosen[i]]
                    top += 1
                break
        while row < 0 and top > 0:
            top -= 1
            if stack_count[top] == INNER:
                row = stack_row[top]
            else:
                _packet_leaf(ox, oy, oz, margin, dx, dy, dz, ordered, order, stack_row[top], stack_count[top],
                             spread, closest, hit, hit_d, closest_bits, spread_bits, ahead)  # fmt: skip


@compiled.njit(nogil=True, error_model="numpy")
def _bvh_packets_wide(first_row, end_row, width, height, basis, wide, wide_links, ordered, order, spheres, image,
                      hits, stop):  # fmt: skip
    """_bvh_packets on the 4-wide tree (bvh.collapse): the same packets,
    the same box, leaf and shading steps, a wide node's four boxes put
    through the packet's interval test together (_wide_mask), then each
    box it leaves through the rays' own test (_rows_enter); the entered
    children visited nearest first along the packet's middle ray, leaves at
    once, the nearest inner child next and the others pushed. Each ray gets
    the nearest sphere of all it could hit, ties to the smaller index."""
    stack_row = np.empty(WIDE_STACK, np.int32)
    stack_count = np.empty(WIDE_STACK, np.int32)
    dx = np.empty(PACKET, np.float32)
    dy = np.empty(PACKET, np.float32)
    dz = np.empty(PACKET, np.float32)
    ix = np.empty(PACKET, np.float32)
    iy = np.empty(PACKET, np.float32)
    iz = np.empty(PACKET, np.float32)
    closest = np.empty(PACKET, np.float32)
    spread = np.empty(7, np.float32)
    closest_bits, spread_bits = closest.view(np.int32), spread.view(np.int32)
    hit = np.empty(PACKET, np.int32)
    hit_d = np.empty(PACKET, np.float32)
    rgb = np.empty((3, PACKET), np.uint8)
    paint = np.empty((4, PACKET), np.float32)
    along = np.empty(WIDTH, np.float32)
    chosen = np.empty(WIDTH, np.int64)
    ox, oy, oz = basis[0, 0], basis[0, 1], basis[0, 2]
    margin = (abs(ox) + abs(oy) + abs(oz)) * PAD
    for y0 in range(first_row, end_row, PACKET_H):
        if stop[0]:
            return
        for x0 in range(0, width, PACKET_W):
            _start_packet(x0, y0, end_row, width, height, basis, dx, dy, dz, ix, iy, iz, closest, hit, hit_d, spread)
            _packet_walk_wide(wide, wide_links, ordered, order, ox, oy, oz, margin, dx, dy, dz, ix, iy, iz, closest,
                              hit, hit_d, spread, closest_bits, spread_bits, stack_row, stack_count, along, chosen,
                              False)  # fmt: skip
            _store_packet(x0, y0, end_row, width, spheres, hit, hit_d, rgb, paint, image, hits)


# A shadow packet's rows (_packet_shadows' rays): directions, their
# inverses, lengths. The loops index the one array by row, not through a row
# per name: each slice taken costs the runtime's reference counting, calls
# that were a large part of a packet's fixed cost.
_DX, _DY, _DZ, _IX, _IY, _IZ, _LEN = range(7)


@numba.njit(inline="always", error_model="numpy")
def _lanes_enter(lx, ly, lz, hx, hy, hz, rays):
    """_rows_enter for a shadow packet: whether any of its LANES rays enters
    the box (planes relative to their origin) nearer than its length."""
    entered = False
    for k in range(LANES):
        t1, t2 = lx * rays[_IX, k], hx * rays[_IX, k]
        t3, t4 = ly * rays[_IY, k], hy * rays[_IY, k]
        t5, t6 = lz * rays[_IZ, k], hz * rays[_IZ, k]
        near = max(min(t1, t2), max(min(t3, t4), min(t5, t6)))
        far = min(max(t1, t2), min(max(t3, t4), max(t5, t6)))
        entered |= (near <= far) & (far > ZERO) & (near <= rays[_LEN, k])
    return entered


@numba.njit(inline="always", error_model="numpy")
def _lanes_leaf(ox, oy, oz, margin, rays, spread, ordered, order, first, count, own, own_inside, blockers, slot):
    """A leaf's spheres against a shadow packet's rays: whether one of them
    blocks a ray (0 < t < the ray's length), each such ray's length made
    _DEAD. The test of traverse.leaf_test, on the same float32 values: the
    sphere `own` the rays leave skipped, or with own_inside met at its far
    root (intersect_ahead). A sphere whose padded box no ray enters is
    skipped after one test for the packet (_missed_by_all, as _packet_leaf
    does). The loop over the rays has no branch and no reduction but an OR:
    LLVM makes it SIMD. blockers[slot]: the last sphere found blocking a
    ray, tested first by the next packet of the slot (_last_blocker)."""
    hits = False
    for j in range(first, first + count):
        original = order[j]
        if original == own and not own_inside:
            continue
        cx, cy, cz, r = ordered[0, j], ordered[1, j], ordered[2, j], ordered[3, j]
        pr = r + bvh_mod.sphere_pad(cx, cy, cz, r)
        if _missed_by_all(
            cx - pr - margin - ox,
            cy - pr - margin - oy,
            cz - pr - margin - oz,
            cx + pr + margin - ox,
            cy + pr + margin - oy,
            cz + pr + margin - oz,
            spread,
        ):
            continue
        if _lanes_sphere(cx - ox, cy - oy, cz - oz, r, rays, original == own):
            blockers[slot] = j
            hits = True
    return hits


@numba.njit(inline="always", error_model="numpy")
def _lanes_sphere(ex, ey, ez, r, rays, far_only):
    """One sphere (centre at (ex, ey, ez) from the rays' origin) against a
    shadow packet's rays: each ray it blocks (0 < t < the ray's length) made
    _DEAD; whether it blocked one."""
    hits = False
    for k in range(LANES):
        t, _d = _intersect_ahead_v(ex, ey, ez, r, rays[_DX, k], rays[_DY, k], rays[_DZ, k], far_only)
        c = rays[_LEN, k]
        hit = (t > ZERO) & (t < c)
        rays[_LEN, k] = _DEAD if hit else c
        hits |= hit
    return hits


# A light's shadow rays from neighbouring points, the tile's pixels one
# after another, are mostly blocked by one sphere: tested first, it answers
# them without a walk. The answer is the walk's (any hit: which sphere
# blocks does not matter), on the same float32 values as _lanes_leaf's. A
# call, not inlined: as fast a frame, for less of the first frame's compile
# (docs/whitted.md#cpu-the-last-blocker-first-issue-27).
@compiled.njit(nogil=True, error_model="numpy", _nrt=False)
def _last_blocker(ox, oy, oz, rays, ordered, order, j, own, own_inside):
    """A shadow packet's rays from (ox, oy, oz) against row j of `ordered`
    (none where j < 0 or it is the sphere the rays leave from outside), each
    ray it blocks made _DEAD: the packet's reach after it (_DEAD once every
    ray is blocked)."""
    if j >= 0:
        original = order[j]
        if original != own or own_inside:
            _lanes_sphere(ordered[0, j] - ox, ordered[1, j] - oy, ordered[2, j] - oz, ordered[3, j], rays,
                          original == own)  # fmt: skip
    return _reach(rays)


@numba.njit(inline="always")
def _reach(rays):
    """The packet's longest ray: _DEAD once every ray is blocked."""
    reach = rays[_LEN, 0]
    for k in range(1, LANES):
        reach = max(reach, rays[_LEN, k])
    return reach


# Inlined into the pixel program (a call of its own measured slower,
# docs/whitted.md#cpu-shadow-rays-as-packets-issue-27): compiled there with the
# program's error model, which leaves its loops over the rays SIMD (they
# divide by nothing).
@numba.njit(inline="always", error_model="numpy")
def _shadow_packet(
    ox, oy, oz, rays, spread, stack, wide, wide_links, ordered, order, own, own_inside, live, blockers, slot
):
    """Any hit of each of a shadow packet's rays from (ox, oy, oz) through
    the 4-wide tree: the bits of the rays blocked, of those in `live`.
    rays[_DX:_DZ + 1]: the unit directions; rays[_LEN]: each ray's length,
    _DEAD where no ray is cast or it is blocked already (_last_blocker)
    (rays[_IX:_IZ + 1]: their inverses, written here); spread (7 + WIDTH)
    and stack (layout.WIDE_STACK): scratch. A ray is blocked where some sphere has 0 < t < its length, which no order
    of the walk changes: the answer of traverse.walk's any hit, ray by ray.
    A node's children are tested as _bvh_packets_wide tests them
    (_wide_mask, then the rays' own test), the leaves at once, the inner
    children pushed nearest on top along the first ray (spread[7:] holds
    where each lies); a blocked ray enters nothing more, and the walk ends
    once every ray is blocked. blockers[slot]: set to the last sphere
    that blocked a ray (_lanes_leaf)."""
    for k in range(LANES):
        rays[_IX, k] = _inverse(rays[_DX, k])
        rays[_IY, k] = _inverse(rays[_DY, k])
        rays[_IZ, k] = _inverse(rays[_DZ, k])
    for a in range(3):
        lo = hi = rays[_IX + a, 0]
        for k in range(1, LANES):
            lo = min(lo, rays[_IX + a, k])
            hi = max(hi, rays[_IX + a, k])
        spread[2 * a] = lo
        spread[2 * a + 1] = hi
    spread[6] = _reach(rays)
    margin = (abs(ox) + abs(oy) + abs(oz)) * PAD
    row = 0
    top = 0
    cdx, cdy, cdz = rays[_DX, 0], rays[_DY, 0], rays[_DZ, 0]
    while row >= 0:
        mask = _wide_mask(wide, row, ox, oy, oz, margin, spread)
        node = row
        row = -1
        base = top
        for c in range(WIDTH):
            if not (mask >> c) & 1:
                continue
            lx, ly, lz, hx, hy, hz = _wide_planes(wide, node, c, ox, oy, oz, margin)
            if not _lanes_enter(lx, ly, lz, hx, hy, hz, rays):
                continue
            ref, count = wide_links[node, W_REF + c], wide_links[node, W_COUNT + c]
            if count == INNER:
                # pushed in order of where the box's centre lies along the
                # first ray, the nearest on top: a blocker near the origin
                # (the commonest: a neighbour) ends the walk soonest
                along = (lx + hx) * cdx + (ly + hy) * cdy + (lz + hz) * cdz
                j = top
                while j > base and spread[7 + j - base - 1] < along:
                    stack[j] = stack[j - 1]
                    spread[7 + j - base] = spread[7 + j - base - 1]
                    j -= 1
                stack[j] = ref
                spread[7 + j - base] = along
                top += 1
            elif count > 0 and _lanes_leaf(ox, oy, oz, margin, rays, spread, ordered, order, ref, count, own,
                                           own_inside, blockers, slot):  # fmt: skip
                reach = _reach(rays)
                if reach == _DEAD:  # every ray blocked
                    return live
                spread[6] = reach
        if top > 0:
            top -= 1
            row = stack[top]
    bits = np.int64(0)  # the rays blocked: those whose length was made _DEAD (a live ray's is positive)
    for k in range(LANES):
        if rays[_LEN, k] == _DEAD:
            bits |= np.int64(1) << np.int64(k)
    return bits & live


@numba.njit(inline="always")
def _whitted_rows(render_pixel, first_row, end_row, width, height, basis, spheres, count, materials, lights, pattern,
                  params, tree, image, hits, counts, stop):  # fmt: skip
    """Whitted shading of the rows first_row..end_row with render_pixel (the
    program through the binary tree, or by brute force), a pixel at a time,
    every ray alone; counts[y]: the rays row y cast, by kind. The packets
    program has its own loop (_whitted_tiles)."""
    stack_row = np.empty(STACK, np.int32)
    stack_t = np.empty(STACK, np.float32)
    rays_f = np.empty((whitted_mod.RAY_STACK, whitted_mod.RAY_FLOATS), np.float32)
    rays_i = np.empty((whitted_mod.RAY_STACK, whitted_mod.RAY_INTS), np.int32)
    for y in range(first_row, end_row):
        if stop[0]:
            return
        primary = shadow = reflection = refraction = 0
        for x in range(width):
            a, b, c, d = render_pixel(
                x, y, width, height, basis, spheres, count, materials, lights, pattern, params, tree, stack_row,
                stack_t, rays_f, rays_i, image, hits,
            )  # fmt: skip
            primary += a
            shadow += b
            reflection += c
            refraction += d
        counts[y, whitted_mod.PRIMARY] = primary
        counts[y, whitted_mod.SHADOW] = shadow
        counts[y, whitted_mod.REFLECTION] = reflection
        counts[y, whitted_mod.REFRACTION] = refraction


_whitted_bvh_pixel, _whitted_all_pixel = _k.render_pixel_whitted["bvh"], _k.render_pixel_whitted["none"]


# One cached kernel for each search, written out at module level: a kernel
# that a factory makes, closing over the pixel program, misses Numba's cache
# in every new process (tried: each run added an index entry, none was hit).
@compiled.njit(nogil=True)
def _whitted_rows_bvh(first_row, end_row, width, height, basis, spheres, count, materials, lights, pattern, params,
                      tree, image, hits, counts, stop):  # fmt: skip
    _whitted_rows(_whitted_bvh_pixel, first_row, end_row, width, height, basis, spheres, count, materials, lights,
                  pattern, params, tree, image, hits, counts, stop)  # fmt: skip


@compiled.njit(nogil=True)
def _whitted_rows_all(first_row, end_row, width, height, basis, spheres, count, materials, lights, pattern, params,
                      tree, image, hits, counts, stop):  # fmt: skip
    _whitted_rows(_whitted_all_pixel, first_row, end_row, width, height, basis, spheres, count, materials, lights,
                  pattern, params, tree, image, hits, counts, stop)  # fmt: skip


_whitted_packets_pixel = _k.render_pixel_whitted["packets"]


@compiled.njit(nogil=True)
def _whitted_rows_packets(first_row, end_row, width, height, basis, spheres, count, materials, lights, pattern,
                          params, tree, image, hits, counts, stop):  # fmt: skip
    """Whitted shading of the rows first_row..end_row (a multiple of
    PACKET_H from the frame's top) through the 4-wide tree (_whitted_tiles),
    given the thread's scratch; tree: (nodes, links, ordered, order, wide,
    wide_links)."""
    nodes, links, ordered, order, wide, wide_links = tree
    lanes = np.empty((7, PACKET), np.float32)
    hit = np.empty(PACKET, np.int32)
    own = (nodes, links, ordered, order, wide, wide_links, np.empty((7, LANES), np.float32),
           np.empty(7 + WIDTH, np.float32), np.empty(WIDE_STACK, np.int32), hit, lanes[6],
           np.empty(PACKET, np.float32), np.zeros(1, np.int64), np.empty(WIDE_STACK, np.int32),
           np.empty(WIDE_STACK, np.int32), np.empty(WIDE_STACK, np.float32),
           np.full(BLOCKER_SLOTS, -1, np.int32))  # fmt: skip
    _whitted_tiles(
        first_row, end_row, width, height, basis, spheres, count, materials, lights, pattern, params, own, lanes,
        np.empty(7, np.float32), np.empty(WIDE_STACK, np.int32), np.empty(WIDE_STACK, np.int32),
        np.empty(WIDTH, np.float32), np.empty(WIDTH, np.int64), np.empty(STACK, np.int32),
        np.empty(STACK, np.float32), np.empty((whitted_mod.RAY_STACK, whitted_mod.RAY_FLOATS), np.float32),
        np.empty((whitted_mod.RAY_STACK, whitted_mod.RAY_INTS), np.int32), image, hits, counts, stop,
    )  # fmt: skip


# Without the runtime's reference counting (_nrt=False): Numba counts the
# references to every array each time one is passed to a function, inlined
# or not, or taken from a tuple, with an atomic add and subtract on the
# array's shared count (NRT_incref, NRT_decref): in the pixel program, whose
# functions pass the frame's arrays down, those took much of a frame's
# CPU time (perf: docs/whitted.md), and as the threads share the arrays,
# each such add moves a cache line between the cores. These functions
# allocate nothing and keep no array: _whitted_rows_packets, which holds the
# scratch, calls them.
@compiled.njit(nogil=True, error_model="numpy", _nrt=False)
def _tile_primaries(x0, y0, end_row, width, height, basis, wide, wide_links, ordered, order, lanes, hit, hit_d, spread,
                    stack_row, stack_count, along, chosen):  # fmt: skip
    """The primary rays of the Whitted frame's PACKET_W x PACKET_H tile at
    (x0, y0) as one packet through the 4-wide tree (_bvh_packets_wide's
    walk, with the Whitted rays' test): lanes[6] (their t, FAR where none),
    hit and hit_d, the answer of traverse.walk for each ray alone. lanes[:6]:
    directions and inverses. A call of its own, with NumPy's error model,
    which leaves the packet's loops SIMD (_kb's note)."""
    closest = lanes[6]
    dx, dy, dz, ix, iy, iz = lanes[0], lanes[1], lanes[2], lanes[3], lanes[4], lanes[5]
    _start_packet(x0, y0, end_row, width, height, basis, dx, dy, dz, ix, iy, iz, closest, hit, hit_d, spread)
    ox, oy, oz = basis[0, 0], basis[0, 1], basis[0, 2]
    margin = (abs(ox) + abs(oy) + abs(oz)) * PAD
    _packet_walk_wide(wide, wide_links, ordered, order, ox, oy, oz, margin, dx, dy, dz, ix, iy, iz, closest, hit,
                      hit_d, spread, closest.view(np.int32), spread.view(np.int32), stack_row, stack_count, along,
                      chosen, True)  # fmt: skip


@compiled.njit(nogil=True, _nrt=False)
def _whitted_tiles(first_row, end_row, width, height, basis, spheres, count, materials, lights, pattern, params, tree,
                   lanes, spread, packet_row, packet_count, along, chosen, stack_row, stack_t, rays_f, rays_i, image,
                   hits, counts, stop):  # fmt: skip
    """_whitted_rows_packets' work, a tile of PACKET_W x PACKET_H pixels at
    a time: the tile's primary rays as one packet (_tile_primaries), then
    each pixel's program, whose reflected and refracted rays walk the wide
    tree alone (_search_wide) and whose shadow rays to a light go as packets
    (_packet_shadows); counts[y]: the rays row y cast, by kind."""
    wide, wide_links, ordered, order = tree[_T_WIDE], tree[_T_WIDE_LINKS], tree[2], tree[3]
    hit, hit_d, lane = tree[_T_HIT], tree[_T_HIT_D], tree[_T_LANE]
    for y0 in range(first_row, end_row, PACKET_H):
        if stop[0]:
            return
        lines = min(PACKET_H, end_row - y0)
        for y in range(y0, y0 + lines):
            for kind in range(len(whitted_mod.KINDS)):
                counts[y, kind] = 0
        for x0 in range(0, width, PACKET_W):
            _tile_primaries(x0, y0, end_row, width, height, basis, wide, wide_links, ordered, order, lanes, hit, hit_d,
                            spread, packet_row, packet_count, along, chosen)  # fmt: skip
            for line in range(lines):
                y = y0 + line
                for i in range(min(PACKET_W, width - x0)):
                    lane[0] = line * PACKET_W + i
                    a, b, c, d = _whitted_packets_pixel(
                        x0 + i, y, width, height, basis, spheres, count, materials, lights, pattern, params, tree,
                        stack_row, stack_t, rays_f, rays_i, image, hits,
                    )  # fmt: skip
                    counts[y, whitted_mod.PRIMARY] += a
                    counts[y, whitted_mod.SHADOW] += b
                    counts[y, whitted_mod.REFLECTION] += c
                    counts[y, whitted_mod.REFRACTION] += d


WHITTED_ROWS = {"bvh": _whitted_rows_bvh, "none": _whitted_rows_all, "packets": _whitted_rows_packets}


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
        whitted: Shading | None = None,
    ):
        """options: the device's (backends.options.checked("cpu", ...); None
        for the defaults); whitted: the Shading of a Whitted frame, None for
        the thesis's shading."""
        if options is None:
            options = checked("cpu", {}, whitted)
        self.options = options
        self.accel, self.kernel = options.accel, options.kernel
        # the threads' stacks counted: under ulimit -v they take address space the frame then lacks
        check_fits("cpu", width, height, spheres.shape[1], host_available_bytes(options.threads), HOST_PIXEL_BYTES)
        if self.accel == "bvh":
            check_bvh_fits(
                "cpu",
                spheres.shape[1],
                host_available_bytes(),
                bvh_mod.BUILD_SPHERE_BYTES,
                width * height * HOST_PIXEL_BYTES,
            )
        self.threads = options.threads
        self.spheres = spheres
        self.count = spheres.shape[1]
        self.width, self.height = width, height
        self.image = np.empty((height, width, 3), dtype=np.uint8)
        self.hits = np.empty((height, width), dtype=np.int32)
        self.constant_count = options.constant_count
        self.bvh = None
        self.build_s = None
        self.whitted = whitted
        self.ray_counts = None
        self.tree_width = None  # the packets' tree: with the BVH
        if whitted is not None:
            # rows take unequal time (mirrors and glass cost more): pulled in chunks, as the BVH's
            self.bands = chunks(height, self.threads)
            workers = min(self.threads, len(self.bands))
            if self.accel == "bvh":
                # 4: the primary and shadow rays as packets through the 4-wide
                # tree, the bounces through it alone (_whitted_rows_packets); 2:
                # every ray alone through the binary tree
                self.tree_width = options.tree_width
            self._kernel = WHITTED_ROWS["packets" if self.tree_width == 4 else self.accel]
            self._row_rays = np.zeros((height, len(whitted_mod.KINDS)), np.int64)
            self.ray_counts = np.zeros(len(whitted_mod.KINDS), np.int64)
            self._none = np.zeros((0, NODE_FLOATS), np.float32)
            if self.accel == "bvh":
                self._build(self.count)
        elif self.accel == "bvh":
            # what the packets shade from: the spheres, or with none a
            # stand-in that every pixel misses (_colour_packet reads sphere
            # 0 for a miss), as the cuda backend uploads
            self.shaded = spheres if self.count else np.zeros((7, 1), np.float32)
            self.bands = chunks(height, self.threads)
            workers = min(self.threads, len(self.bands))
            self.tree_width = options.tree_width
            self._kernel = _bvh_packets_wide if self.tree_width == 4 else _bvh_packets
            self._build(self.count)
        else:
            self.bands = bands(height, self.threads)
            workers = len(self.bands)
            if self.kernel == "fast":
                self._kernel = _fast_band
                self.relative = np.zeros((4, self.count), np.float32)
            else:
                self._kernel = _constant_band(self.count) if self.constant_count else _render_band
        # Every band is traced on the pool's threads, a single one too: the
        # main thread only waits, so that Ctrl-C reaches it mid-frame (trace).
        self._pool = ThreadPoolExecutor(workers)
        self._workers = workers
        self._stop = np.zeros(1, np.uint8)  # set: every kernel returns at its next row (trace)

    def update(self, spheres: np.ndarray) -> str | None:
        """The spheres moved: the next frames trace them, through a tree
        rebuilt on the host (the contract's update)."""
        self.spheres = check_moved(spheres, self.spheres)
        if self.accel != "bvh":
            return None
        if self.whitted is None:
            self.shaded = self.spheres if self.count else np.zeros((7, 1), np.float32)
        self._build(self.bvh.count)
        return "build"

    def _build(self, count: int) -> None:
        """The BVH of the first `count` spheres; its build time in build_s
        (with the collapse into 4-wide nodes, where the packets walk those)."""
        self.bvh = bvh_mod.build(self.spheres[:, :count], threads=min(self.threads, default_threads()))
        self.build_s = self.bvh.build_s
        if self.tree_width == 4:
            if not bvh_mod.collapse_in_python(self.bvh):
                bvh_mod.compile_collapse()
            start = time.perf_counter()
            self.wide = bvh_mod.collapse(self.bvh)
            self.build_s += time.perf_counter() - start

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
        if self.whitted is not None:
            w = self.whitted
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
            _prepare(basis, self.spheres, count, self.relative)
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
            cut = chunks if self.accel == "bvh" or self.whitted is not None else _bands_of
            bands = [(first + a, first + b) for a, b in cut(end - first, self.threads)]
        if self._pool is None:  # closed, and used again
            self._pool = ThreadPoolExecutor(self._workers)
        if self.accel == "bvh" or self.whitted is not None:
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
