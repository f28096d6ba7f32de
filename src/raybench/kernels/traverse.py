"""Nearest hit through the BVH (raybench.bvh's layout): the same answer as
trace.nearest_hit's loop over every primitive, bit for bit. The walk knows
nothing of the primitive but its leaf test (kernels/primitives).

Same answer because:
- every primitive a walk reaches is tested with the primitive's own hit on
  the very float32 values the brute-force loop uses, so each t and datum is
  the same;
- the brute-force loop keeps the first primitive of smallest t (strict <);
  the walk meets them in another order, so on equal t it keeps the smaller
  ORIGINAL index, which picks the same one;
- no primitive the exact test would accept is ever skipped: a box is
  entered if its slab interval (computed on the box grown by the builder's
  padding and a margin for the camera, see axis_setup) reaches [0, closest]
  inclusive, and the float32 hit point of an accepted primitive lies within
  a few epsilons of its size and distance from it, far inside that padding
  (the primitive's pad).
The box test may be loose (it only decides what to visit); it never
overflows to NaN: direction components under TINY are replaced by +-TINY,
so 1/d stays finite and (plane - origin) * (1/d) cannot be inf * 0.
"""

from types import SimpleNamespace

import numpy as np

from ..layout import CHILD_BOX, COUNT, INNER, PAD, REF
from .constants import FAR, ONE, ZERO

# Small enough that replacing a zero component moves the ray by under 1e-20
# of its length (far under the padding), large enough that 1/TINY times the
# largest scene extent (2e15) is finite in float32.
TINY = np.float32(1e-20)
# Array indices are unsigned: a signed one carries Python's negative-index
# wraparound, a compare and a select on every node and sphere read of the
# walk (the CUDA fast kernel and the CPU's cull loops dropped it the same way).
_U = np.uint64


def make(jit, prim, read_row=None, vote=None, voted_jit=None, leaf_jit=None, kind="sphere", positions=False):
    """The walks over `jit`, for the primitive whose compiled functions are
    `prim` (a primitive module's make: kernels/primitives, its name `kind`);
    the leaf test is the only part that asks it anything. leaf_jit: the
    leaf test's decorator (default jit): the CPU compiles it as a function
    that the walk calls, not inlined at the walk's two leaf sites. read_row(nodes, links, row): a
    node's row as its 16 values; by default the arrays are read a value at
    a time, and a backend's own may read them in fewer, wider loads from a
    layout of its own (cuda's wavefront). vote(p): whether p holds for any
    ray of a group that walks as one packet (a CUDA block's barrier); given,
    the walk is also compiled voted (_walk_body), as packet_walk, with
    voted_jit (default jit). positions: the walks answer a primitive's
    position in the tree's order (its column of `ordered`), not its original
    index, for a backend whose `ordered` is the whole scene's buffer in the
    tree's order, which its shading reads too (cuda's meshes: no second copy
    of the triangles); the primitive a Whitted ray leaves (own) is given the
    same way, and ties still go to the smaller original index (order's), so
    the answer is the same primitive. A namespace of the walks and the parts
    the WGSL twins are held to."""
    if read_row is None:

        @jit
        def read_row(nodes, links, row):
            """A node's row: both children's boxes (lo x, y, z, hi x, y, z),
            then their refs and counts (layout's columns)."""
            a, b = _U(CHILD_BOX[0]), _U(CHILD_BOX[1])
            return (
                nodes[row, a], nodes[row, a + _U(1)], nodes[row, a + _U(2)], nodes[row, a + _U(3)],
                nodes[row, a + _U(4)], nodes[row, a + _U(5)], nodes[row, b], nodes[row, b + _U(1)],
                nodes[row, b + _U(2)], nodes[row, b + _U(3)], nodes[row, b + _U(4)], nodes[row, b + _U(5)],
                links[row, _U(REF)], links[row, _U(REF + 1)], links[row, _U(COUNT)], links[row, _U(COUNT + 1)],
            )  # fmt: skip

    hit_closest, hit_ahead, meets_own = prim.leaf_hit, prim.leaf_hit_ahead, prim.meets_own

    @jit
    def inverse(d):
        """1/d for the slab test, finite: |d| raised to at least TINY, its sign kept."""
        return ONE / (max(d, TINY) if d >= ZERO else min(d, -TINY))

    @jit
    def axis_setup(o, d, margin):
        """One axis of the ray for the slab test: 1/d, and the origin shifted
        by the margin for the box's low plane and for its high one, so the
        slabs are those of the box grown by `margin` on every side; the two
        origins come times 1/d, so that a plane's distance is one
        multiply-add (plane * 1/d - origin * 1/d) where the GPU fuses them,
        a step of the walk's fewer instructions (docs/notes/whitted.md). Its
        rounding differs from (plane - origin) * 1/d by an ulp or two of
        the terms, far inside the builder's padding and the margin."""
        inv = inverse(d)
        return inv, (o + margin) * inv, (o - margin) * inv

    @jit
    def slab(lo_x, lo_y, lo_z, hi_x, hi_y, hi_z, ix, iy, iz, lx, ly, lz, hx, hy, hz):
        """The (near, far) distances of the ray through one child box; near >
        far where it misses. Both planes of each axis come as stored (read
        at fixed columns by read_row) and are put in order by min and max
        (the sign of 1/d decides which is near), so every read of the row is
        at a constant offset: choosing the column by the ray's direction cost
        an address computation per read
        (docs/notes/bvh-walk.md#gpu-measured-on-the-h200). The values are the same:
        float subtraction and multiplication keep the planes' order.
        An empty child's inverted box (lo layout.EMPTY, hi -EMPTY) comes out as
        a slab around every ray: visited as the leaf of no spheres that it is."""
        a0 = lo_x * ix - lx
        a1 = lo_y * iy - ly
        a2 = lo_z * iz - lz
        b0 = hi_x * ix - hx
        b1 = hi_y * iy - hy
        b2 = hi_z * iz - hz
        near = max(min(a0, b0), max(min(a1, b1), min(a2, b2)))
        far = min(max(a0, b0), min(max(a1, b1), max(a2, b2)))
        return near, far

    @jit
    def ray_axes(ox, oy, oz, dx, dy, dz):
        """The ray's three axes for the slab tests (axis_setup), every box grown
        by the camera's margin: (1/dx, 1/dy, 1/dz, the low planes' origins
        times 1/d, the high planes' origins times 1/d)."""
        margin = (abs(ox) + abs(oy) + abs(oz)) * PAD
        ix, lx, hx = axis_setup(ox, dx, margin)
        iy, ly, hy = axis_setup(oy, dy, margin)
        iz, lz, hz = axis_setup(oz, dz, margin)
        return ix, iy, iz, lx, ly, lz, hx, hy, hz

    @jit
    def children(nodes, links, node, ix, iy, iz, lx, ly, lz, hx, hy, hz):
        """A node's two children: the ray's (near, far) through each one's box,
        then their refs and counts (bvh's layout)."""
        (a_lx, a_ly, a_lz, a_hx, a_hy, a_hz, b_lx, b_ly, b_lz, b_hx, b_hy, b_hz, a_ref, b_ref, a_count,
         b_count) = read_row(nodes, links, node)  # fmt: skip
        a_near, a_far = slab(a_lx, a_ly, a_lz, a_hx, a_hy, a_hz, ix, iy, iz, lx, ly, lz, hx, hy, hz)
        b_near, b_far = slab(b_lx, b_ly, b_lz, b_hx, b_hy, b_hz, ix, iy, iz, lx, ly, lz, hx, hy, hz)
        return a_near, a_far, b_near, b_far, a_ref, b_ref, a_count, b_count

    @jit
    def centre_along(nodes, row, col, ox, oy, oz, cx, cy, cz):
        """How far along the direction (cx, cy, cz) from the origin the centre
        of the child box at column col lies: the order in which the packet
        walks (cpu, cuda) take a node's children, the same for all the
        packet's rays. An empty child's inverted box (lo layout.EMPTY, hi -EMPTY)
        gives 0, not NaN."""
        half = np.float32(0.5)
        return (
            (half * (nodes[row, col] + nodes[row, col + _U(3)]) - ox) * cx
            + (half * (nodes[row, col + _U(1)] + nodes[row, col + _U(4)]) - oy) * cy
            + (half * (nodes[row, col + _U(2)] + nodes[row, col + _U(5)]) - oz) * cz
        )

    def leaf_test(ox, oy, oz, dx, dy, dz, ordered, order, first, count, closest, hit, hit_d, ahead, own, own_inside):
        """The exact test on a leaf's primitives; the nearest so far, ties to
        the smaller original index. ahead: a Whitted ray's test (the
        primitive's hit_ahead), where the primitive `own` the ray leaves is
        skipped unless the primitive says a ray can meet it again (meets_own:
        a sphere, going into it, at its far root). Else the thesis's test
        (the primitive's hit)."""
        # A while loop on 32-bit indices: range() over 64-bit ones made the
        # GPU work out a trip count and an unrolled remainder in 64-bit
        # integer steps at every leaf (docs/notes/whitted.md)
        j = np.uint32(first)
        end = np.uint32(first + count)
        while j < end:
            k = j
            j = np.uint32(j + np.uint32(1))
            # where the walk answers positions its answer is k itself, and k's original index is read
            # on a tie alone
            at = np.int32(k) if positions else order[k]
            if ahead and at == own and not meets_own(own_inside):
                continue
            if ahead:
                t, d = hit_ahead(ordered, k, ox, oy, oz, dx, dy, dz, at == own)
            else:
                t, d = hit_closest(ordered, k, ox, oy, oz, dx, dy, dz)
            if t > ZERO and (
                t < closest or (t == closest and ((hit >= 0 and order[k] < order[_U(hit)]) if positions else at < hit))
            ):
                closest = t
                hit = at
                hit_d = d
        return closest, hit, hit_d

    # Inlined at both of the walk's leaf sites, each with the primitive's two
    # tests, a triangle's walk took Numba minutes to compile on the CPU: as
    # one called function it compiles once, and a call per leaf is little
    # beside the primitives it tests (docs/notes/startup.md, "A mesh's first
    # picture"). Named after its kind: Numba names machine code by qualified name and a per-process
    # counter, so two kinds' leaf tests compiled into the disk cache by two
    # processes could carry one symbol (whitted.make's find says what that did).
    leaf_test.__name__ = f"leaf_test_{kind}" + ("_at" if positions else "")
    leaf_test.__qualname__ = leaf_test.__qualname__.replace("leaf_test", leaf_test.__name__)
    leaf_test = (leaf_jit or jit)(leaf_test)

    walk_from = _walk_body(jit, ray_axes, children, centre_along, leaf_test, None)
    voted = None if vote is None else _walk_body(voted_jit or jit, ray_axes, children, centre_along, leaf_test, vote)

    @jit
    def walk_ray(
        ox, oy, oz, dx, dy, dz, t_max, any_hit, ahead, own, own_inside, nodes, links, ordered, order, stack_row, stack_t
    ):
        """The one BVH walk for any ray: (original index of the nearest primitive
        with 0 < t < t_max, or -1; its t; its half-chord d). any_hit: stop at
        the first such primitive (a shadow ray's blocker), whichever it is.
        ahead, own, own_inside: the secondary rays' test (leaf_test).
        stack_row / stack_t: the walk's stack, layout.STACK entries, given by
        the backend (a CUDA thread's local array, a CPU thread's own)."""
        return walk_from(ox, oy, oz, dx, dy, dz, dx, dy, dz, t_max, any_hit, ahead, own, own_inside, nodes, links,
                         ordered, order, stack_row, stack_t)  # fmt: skip

    @jit
    def nearest_hit_bvh(ox, oy, oz, dx, dy, dz, nodes, links, ordered, order, stack_row, stack_t):
        """(original index of the nearest primitive with t > 0 or -1, its
        hit's datum): walk() for the thesis's primary rays."""
        hit, _t, hit_d = walk_ray(
            ox, oy, oz, dx, dy, dz, FAR, False, False, -1, False, nodes, links, ordered, order, stack_row, stack_t
        )
        return hit, hit_d

    return SimpleNamespace(
        nearest_hit_bvh=nearest_hit_bvh,
        inverse=inverse,
        ray_axes=ray_axes,
        children=children,
        walk=walk_ray,
        packet_walk=voted,
    )


# What a voted walk pushes as the entry distance of a child its ray does not
# enter: beyond any closest hit, so it never votes to visit that child.
_MISS = np.float32(np.inf)


def _walk_body(jit, ray_axes, children, centre_along, leaf_test, vote):
    """walk_from, the BVH walk (traverse.wgsl's twin of the name): one source
    for a ray alone (vote None) and for a group of rays that walk as one
    packet (vote given: a CUDA block's rays; in WGSL, a subgroup's).

    Alone, the ray takes a node's nearer child first, skips a box it enters
    no nearer than its closest hit, and with any_hit stops at the first
    primitive found. Voted, the packet visits a child if any of its rays
    enters it (vote), and each ray tests only the leaves it enters itself, so
    the node, the stack's rows and every branch are the same for all the
    group's rays: one node fetch serves them all, and they never diverge.
    The children are then taken in the order of their centres along the
    group's central ray (cdx, cdy, cdz), the same for every ray without a
    vote (faster than voting on the order:
    docs/notes/bvh-walk.md#packets-of-rays-on-the-gpu-kept). Every ray takes
    part in every vote, so a voted walk takes no any_hit: it walks the
    thesis's primary rays (any_hit and ahead False). Same hits either
    way: a ray's hit is in a box it enters, and the packet enters every box
    one of its rays does (or, off the stack, one it entered nearer than its
    closest hit). `voted` is a constant of each compile: the other branches
    are not compiled into it."""
    voted = vote is not None
    if vote is None:

        @jit
        def vote(p):
            return p

    @jit
    def walk_from(ox, oy, oz, dx, dy, dz, cdx, cdy, cdz, t_max, any_hit, ahead, own, own_inside, nodes, links,
                  ordered, order, stack_row, stack_t):  # fmt: skip
        if voted:
            # a packet's primary rays: the flags made constants of this compile,
            # so that the thesis's test alone is compiled into its leaves
            any_hit = False
            ahead = False
        ix, iy, iz, lx, ly, lz, hx, hy, hz = ray_axes(ox, oy, oz, dx, dy, dz)
        closest = t_max
        hit = np.int32(-1)  # the primitives' original indices are int32: compared in one step, not two
        hit_d = ZERO
        row = 0
        top = _U(0)
        while row >= 0:
            node = _U(row)
            a_near, a_far, b_near, b_far, a_ref, b_ref, a_count, b_count = children(
                nodes, links, node, ix, iy, iz, lx, ly, lz, hx, hy, hz
            )
            # the nearer child first: its hits can rule the far one out (and
            # a shadow ray meets a blocker sooner: the tree's order measured
            # slower on the GPU, docs/notes/whitted.md); voted, the one whose
            # centre lies nearer along the central ray (guarding an empty
            # child's case with a branch, or clamping its planes, cost more
            # than the builder storing them finite: docs/notes/bvh-walk.md)
            a_in = a_near <= a_far and a_far > ZERO and a_near <= closest
            b_in = b_near <= b_far and b_far > ZERO and b_near <= closest
            if voted:
                b_first = centre_along(nodes, node, _U(CHILD_BOX[1]), ox, oy, oz, cdx, cdy, cdz) < centre_along(
                    nodes, node, _U(CHILD_BOX[0]), ox, oy, oz, cdx, cdy, cdz
                )
            else:
                b_first = b_near < a_near
            # voted, both votes at once, before either child's leaf is tested
            # (the second after the first child's leaf test measured slower:
            # docs/notes/one-source.md#one-walk-for-a-ray-and-a-packet)
            any_a = vote(a_in)
            any_b = vote(b_in)
            if b_first:
                a_near, a_ref, a_count, a_in, any_a, b_near, b_ref, b_count, b_in, any_b = (
                    b_near, b_ref, b_count, b_in, any_b, a_near, a_ref, a_count, a_in, any_a
                )  # fmt: skip
            row = -1
            if any_a:
                if a_count == INNER:
                    row = a_ref
                elif a_in:
                    closest, hit, hit_d = leaf_test(ox, oy, oz, dx, dy, dz, ordered, order, a_ref, a_count, closest,
                                                    hit, hit_d, ahead, own, own_inside)  # fmt: skip
            b_in = b_in and b_near <= closest  # the first child's hits can rule the second out
            if not voted:
                any_b = b_in
            if any_b:
                if b_count != INNER:
                    if b_in:
                        closest, hit, hit_d = leaf_test(ox, oy, oz, dx, dy, dz, ordered, order, b_ref, b_count,
                                                        closest, hit, hit_d, ahead, own, own_inside)  # fmt: skip
                elif row < 0:
                    row = b_ref
                else:
                    stack_row[top] = b_ref
                    if voted:
                        stack_t[top] = b_near if b_in else _MISS
                    elif not any_hit:  # a shadow ray's t_max never shrinks: nothing pushed can fall behind it
                        stack_t[top] = b_near
                    top += _U(1)
            if any_hit and hit >= 0:
                return hit, closest, hit_d
            while row < 0 and top > _U(0):
                top -= _U(1)
                if any_hit or vote(stack_t[top] <= closest):
                    row = stack_row[top]
        return hit, closest, hit_d

    return walk_from
