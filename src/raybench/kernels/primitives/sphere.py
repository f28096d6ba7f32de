"""The sphere: everything the builders, the walks and the shading know about it.

A primitive module answers the same few questions for every device (pbrt's
Shape, tinybvh's custom geometry): how its leaf buffer is read, its padded
bounds, the closest-hit and any-hit tests, the surface at a hit, and what the
thesis's shading divides by. Nothing outside this module (and its WGSL twin,
backends/wgpu/sphere.wgsl) reads a sphere's rows or knows that it has a
radius; the walks (kernels/traverse.py, kernels/packets.py) take these
functions from make(jit) and never ask which kind of primitive a leaf holds.

Its buffer: rows CX, CY, CZ, RADIUS of layout (Scene.spheres), a row a field;
the tree's `ordered` copy holds the same four rows in leaf order, so one
reader serves both.

A hit's datum (the second value of every test): the half-chord d, which the
thesis's shading uses. The walks carry it through untouched.

The ray against the sphere is the thesis's rayVsSphere (Appendix A), with the
discriminant in a form that keeps its digits in float32; and the cheap test
that lets the fast kernels skip most spheres without changing a pixel.
"""

import math

import numpy as np

from ...layout import BLUE, CX, CY, CZ, GREEN, NODE_COST, PAD, RADIUS, RED, SPHERE_ROWS
from ..constants import ONE, ZERO
from .answers import answers, boxed_window, footprinted_always, unaimed

# The CPU walks inline this kind's tests at their leaves (compiled.leaf_test): a
# few instructions, inlined as the packets were measured with them.
INLINE_TESTS = True
# The cpu's packets of primary rays (kernels/packets.py): 16x8 pixels, of 4x4 to
# 32x8 the fastest on random spheres (docs/notes/bvh-walk.md).
PACKET_SHAPE = (16, 8)
# Its packets test a leaf's sphere on all their rays: its box's footprint
# (kernels/footprint.py) is for primitives that cover a few pixels.
PACKET_FOOTPRINT = False
# Whitted's packets program on the cpu traces a hit's shadow rays to a light as
# one packet through the 4-wide tree (kernels/shadow_packets.py), not a ray at a
# time: for spheres the packet, with its last blocker tried first, is faster.
SHADOW_PACKETS = True
# What a message calls a scene's primitives of this kind.
NOUN = "spheres"
# Rows of the leaf buffer (bvh's `ordered`): centre x, y, z and radius.
LEAF_ROWS = 4
# The cpu's leaf buffer in rows, a row a value ("C"): a sphere's four values held together ("F")
# gained nothing and cost Whitted's rays a little
# (docs/triangles.md#a-triangles-nine-values-together-on-the-cpu-2026-12-05).
CPU_LEAF_ORDER = "C"
# What the SAH counts a node's visit, in this kind's tests, in a tree that only the cpu's packets
# of primary rays walk: layout.NODE_COST, every tree's (the triangle's larger leaves made the
# thesis's frames no faster: docs/triangles.md, "Larger leaves for the cpu's packets").
PACKETS_NODE_COST = NODE_COST
# And in the host's tree that cuda walks: every tree's.
CUDA_NODE_COST = NODE_COST
# Rows of the scene's buffer (Scene.spheres) that the shading reads: with the colour.
SCENE_ROWS = SPHERE_ROWS
# A packed leaf copy (make's words, pack_leaf): float64 words a sphere, its four float32.
PACKED_WORDS = 2
# The cull test's slack, relative to |EO|^2 + r^2: 64 float32 epsilons, several
# times the rounding of either discriminant (derivation in prepare).
CULL_SLACK = np.float32(64.0 * 2.0**-24)
# The cull threshold's slack, relative to |EO|: 64 float32 epsilons, covering
# a v computed with fused multiply-adds in one place and without in another.
ALONG_SLACK = np.float32(64.0 * 2.0**-24)


def pad(cx, cy, cz, r):
    """The padding of a sphere's box (layout.PAD's rule), as every builder
    and the CPU packets' leaf cull compute it: the box is the centre
    +- (r + pad). Python's abs: numba and numba-cuda compile it (the GPU
    target has no NumPy ufuncs), and it takes arrays too (the tests' references)."""
    return (r + (abs(cx) + abs(cy) + abs(cz))) * PAD


def shared_colour(buffer):
    """None: each of the kind's columns keeps its own colour (the triangle's
    shared_colour says what a mesh of one colour keeps once)."""
    return None


def centres(buffer):
    """The centres of the boxes of a buffer's spheres, (3, N): extent's
    centres, read on the host (the GPU builders' Morton codes)."""
    return buffer[CX : CZ + 1]


def make(jit, words=None):
    """The sphere's functions compiled with `jit`: a namespace. words: a
    backend's bit cast of one float64 load into its two float32 words; with
    it the leaf tests read the tree's spheres from a copy of a row a sphere
    (LEAF_ROWS float32, seen as float64 pairs: cuda's wavefront), in two
    loads where the rows take four."""
    padding = jit(pad)

    @jit
    def read(buffer, k):
        """Sphere k of a buffer of this layout (the scene's spheres, or the
        tree's ordered copy): (cx, cy, cz, r)."""
        return buffer[CX, k], buffer[CY, k], buffer[CZ, k], buffer[RADIUS, k]

    if words is None:
        read_leaf = read
    else:

        @jit
        def read_leaf(buffer, k):
            """Sphere k of the tree's copy a row a sphere, as float64 pairs:
            (cx, cy) in one load, (cz, r) in the other."""
            cx, cy = words(buffer[k, np.uint64(0)])
            cz, r = words(buffer[k, np.uint64(1)])
            return cx, cy, cz, r

    @jit
    def along(ex, ey, ez, dx, dy, dz):
        """v = EO.dir, how far along the ray the sphere's centre lies: the
        first line of intersect_relative, and all of the cull test."""
        return ex * dx + ey * dy + ez * dz

    @jit
    def chord(ex, ey, ez, r, dx, dy, dz):
        """v = EO.dir and the discriminant r^2 - |EO - v dir|^2: the ray meets
        the sphere where disc >= 0, at v -+ sqrt(disc)."""
        v = along(ex, ey, ez, dx, dy, dz)
        px = ex - v * dx
        py = ey - v * dy
        pz = ez - v * dz
        return v, r * r - (px * px + py * py + pz * pz)

    @jit
    def intersect_relative(ex, ey, ez, r, dx, dy, dz):
        """Distance t along the unit ray to the sphere's near surface and the
        half-chord d (the thesis's `d`, which its shading uses); t = -1 on a miss.
        (ex, ey, ez) is EO, the sphere's centre minus the ray's origin.
        disc = r^2 - |EO - v dir|^2 equals the thesis's r^2 - (EO.EO - v^2) but
        keeps its digits in float32: the thesis's form subtracts two squares of
        the sphere's distance and loses everything for small, far spheres.
        """
        v, disc = chord(ex, ey, ez, r, dx, dy, dz)
        if disc < ZERO:
            return np.float32(-1.0), ZERO
        d = np.float32(math.sqrt(disc))
        return v - d, d

    @jit
    def intersect_ahead(ex, ey, ez, r, dx, dy, dz, far_only):
        """The secondary rays' test: the first crossing of the sphere ahead of
        the origin, the near root from outside and the far root from inside
        (a ray in a glass sphere, a camera in one); far_only takes the far
        root whatever the near one, for a ray that starts on this very sphere
        and goes into it. Same (t, d) as intersect_relative where the near
        root is ahead; t <= 0 where nothing is."""
        v, disc = chord(ex, ey, ez, r, dx, dy, dz)
        if disc < ZERO:
            return np.float32(-1.0), ZERO
        d = np.float32(math.sqrt(disc))
        t = v - d
        if far_only or t <= ZERO:
            t = v + d
        return t, d

    @jit
    def intersect(ox, oy, oz, dx, dy, dz, cx, cy, cz, r):
        """intersect_relative for a ray from (ox, oy, oz)."""
        return intersect_relative(cx - ox, cy - oy, cz - oz, r, dx, dy, dz)

    def tests(read):
        """hit and hit_ahead on a buffer that `read` reads."""

        @jit
        def hit(buffer, k, ox, oy, oz, dx, dy, dz):
            """The thesis's primary test of sphere k of a buffer: (t, d)."""
            cx, cy, cz, r = read(buffer, k)
            return intersect(ox, oy, oz, dx, dy, dz, cx, cy, cz, r)

        @jit
        def hit_ahead(buffer, k, ox, oy, oz, dx, dy, dz, is_own):
            """The secondary rays' test of sphere k of a buffer
            (intersect_ahead); is_own: k is the sphere the ray leaves, going
            into it (meets_own), met at its far root."""
            cx, cy, cz, r = read(buffer, k)
            return intersect_ahead(cx - ox, cy - oy, cz - oz, r, dx, dy, dz, is_own)

        return hit, hit_ahead

    # on the scene's spheres (by original index), and on the tree's leaves
    hit, hit_ahead = tests(read)
    leaf_hit, leaf_hit_ahead = (hit, hit_ahead) if words is None else tests(read_leaf)

    @jit
    def seen_from(row, ox, oy, oz):
        """A leaf's row (read_leaf's) as rays from (ox, oy, oz) see it,
        worked out once for a packet of rays that share that origin: (EO, r),
        hit_from's and hit_ahead_from's first argument."""
        cx, cy, cz, r = row
        return cx - ox, cy - oy, cz - oz, r

    @jit
    def from_origin(buffer, k, ox, oy, oz):
        """seen_from for sphere k of the tree's leaf buffer."""
        return seen_from(read_leaf(buffer, k), ox, oy, oz)

    @jit
    def hit_from(seen, dx, dy, dz):
        """leaf_hit for one ray of the packet whose origin `seen` is from."""
        ex, ey, ez, r = seen
        return intersect_relative(ex, ey, ez, r, dx, dy, dz)

    @jit
    def hit_ahead_from(seen, dx, dy, dz, is_own):
        """leaf_hit_ahead for one ray of the packet whose origin `seen` is from."""
        ex, ey, ez, r = seen
        return intersect_ahead(ex, ey, ez, r, dx, dy, dz, is_own)

    @jit
    def meets_own(own_inside):
        """Whether a ray that leaves a sphere can meet it again: only going
        into it (own_inside), at the far root. A ray leaving a sphere outwards
        cannot (it is convex), so no rounding of the ray's origin can make a
        sphere shadow or reflect itself: the walks skip it."""
        return own_inside

    @jit
    def box_of(row):
        """A leaf's row's (read_leaf's) padded box: (lo x, y, z, hi x, y, z)."""
        cx, cy, cz, r = row
        pr = r + padding(cx, cy, cz, r)
        return cx - pr, cy - pr, cz - pr, cx + pr, cy + pr, cz + pr

    @jit
    def bounds(buffer, k):
        """Sphere k's padded box: box_of its row of the tree's leaf buffer."""
        return box_of(read_leaf(buffer, k))

    @jit
    def extent(buffer, k):
        """Sphere k of the scene's buffer as the builders see it: its padded
        box as a centre and half its size on each axis, (cx, cy, cz, hx, hy,
        hz). The box's centre is the sphere's, so its lows and highs are
        box_of's to the bit: centre -+ half."""
        cx, cy, cz, r = read(buffer, k)
        pr = r + padding(cx, cy, cz, r)
        return cx, cy, cz, pr, pr, pr

    @jit
    def copy_leaf(buffer, k, leaves, at):
        """Sphere k of the scene's buffer into the tree's leaf buffer (the
        builders' `ordered`) at column `at`: the scene's very values."""
        cx, cy, cz, r = read(buffer, k)
        leaves[0, at] = cx
        leaves[1, at] = cy
        leaves[2, at] = cz
        leaves[3, at] = r

    @jit
    def pack_leaf(leaves, k, rows):
        """Sphere k of the tree's leaf buffer into its row of a packed copy
        (rows: float32, 2 * PACKED_WORDS columns, which read_leaf reads
        through `words`): its LEAF_ROWS values, as they are."""
        for c in range(LEAF_ROWS):
            rows[k, c] = leaves[c, k]

    @jit
    def surface(ox, oy, oz, dx, dy, dz, t, i, spheres):
        """The hit of a ray on sphere i at t: (point, unit normal on the ray's
        side, cos_i on that side, whether the ray meets the sphere from
        within)."""
        px = ox + t * dx
        py = oy + t * dy
        pz = oz + t * dz
        cx, cy, cz, r = read(spheres, i)
        inv_r = ONE / r
        nx = (px - cx) * inv_r
        ny = (py - cy) * inv_r
        nz = (pz - cz) * inv_r
        inv_n = ONE / np.float32(math.sqrt(nx * nx + ny * ny + nz * nz))
        nx *= inv_n
        ny *= inv_n
        nz *= inv_n
        cos_i = -(nx * dx + ny * dy + nz * dz)
        inside = cos_i < ZERO  # the ray meets the sphere from within
        if inside:
            nx, ny, nz, cos_i = -nx, -ny, -nz, -cos_i
        return px, py, pz, nx, ny, nz, cos_i, inside

    @jit
    def colour(spheres, i):
        """Sphere i's colour (red, green, blue): what the thesis's shading
        darkens towards the rim, and Whitted's diffuse colour."""
        return spheres[RED, i], spheres[GREEN, i], spheres[BLUE, i]

    @jit
    def rim(spheres, i):
        """What the thesis's shading divides a hit's datum (the half-chord)
        by: the radius (shade.shade_hit)."""
        return spheres[RADIUS, i]

    @jit
    def prepare(ox, oy, oz, cx, cy, cz, r):
        """Per frame and sphere: EO (exactly as intersect computes it) and
        the cull threshold s of may_hit: a ray can only hit where v > s.

        Why it holds. intersect_relative accepts only t = v - d > 0 with
        d >= 0, so v > 0. For a unit ray, |EO - v dir|^2 = |EO|^2 - v^2, so
        disc >= 0 needs v^2 >= q = |EO|^2 - r^2 (the thesis's cheap form).
        Hence a hit needs v > sqrt(q) (v > 0 where q <= 0). In float32 the
        rounding of either discriminant, and a ray of length 1 only to a few
        epsilons, move q by a few epsilons of |EO|^2 + r^2: lowered by
        CULL_SLACK (|EO|^2 + r^2), q is below every v^2 the exact test can
        accept by a margin that also covers the rounding of the square root.
        v itself may be computed with or without fused multiply-adds (a
        compiler's choice), which moves it by a few epsilons of |EO|: s is
        lowered by ALONG_SLACK |EO|. So the test only ever skips certain
        misses, and the fast kernels give the same pixels as the simple ones.
        """
        ex = cx - ox
        ey = cy - oy
        ez = cz - oz
        e2 = ex * ex + ey * ey + ez * ez
        r2 = r * r
        q = (e2 - r2) - CULL_SLACK * (e2 + r2)
        s = np.float32(math.sqrt(q)) if q > ZERO else ZERO
        return ex, ey, ez, s - ALONG_SLACK * np.float32(math.sqrt(e2))

    @jit
    def prepare_at(buffer, k, ox, oy, oz):
        """prepare for sphere k of a buffer, from the origin (ox, oy, oz)."""
        cx, cy, cz, r = read(buffer, k)
        return prepare(ox, oy, oz, cx, cy, cz, r)

    @jit
    def may_hit(ex, ey, ez, s, dx, dy, dz):
        """False only where the ray certainly misses the sphere (see
        prepare): one dot product and a compare."""
        return along(ex, ey, ez, dx, dy, dz) > s

    aim, turned, hit_aimed = unaimed(jit, hit_from)
    window = boxed_window(jit, box_of)
    footprinted = footprinted_always(jit, PACKET_FOOTPRINT)
    hit_whole = hit_from  # what the packets test an unfootprinted primitive with
    return answers(
        "sphere",
        {**locals(), "pad": padding},  # the module's pad, compiled
        ("along", "chord", "intersect_relative", "intersect_ahead", "prepare", "prepare_at", "may_hit"),
    )
