"""The triangle: everything the builders, the walks and the shading know about it.

The same answers as sphere.py (kernels/primitives/__init__.py lists them),
for one triangle of a mesh. Nothing outside this module reads a triangle's
rows; the walks take these functions from make(jit).

Its buffers (layout's TRI_ rows, a column a triangle): the leaf buffer is
the nine rows of vertices A, B and C (x, y, z each); the scene's buffer
(meshes.mesh_leaves) is the same nine rows, then three of its colour
(which `colour` reads), and where the mesh has vertex normals nine more,
the corners' normals, which only `surface` reads. The
builders' copy_leaf copies the nine, so the tree's leaves never carry the
normals. make(jit, words) reads a packed leaf copy of PACKED_WORDS float64
a triangle (its nine float32 and one of padding).

The test is Woop, Benthin and Wald's watertight ray/triangle intersection
(JCGT 2(1), 2013): the axis along which the ray goes fastest becomes z, the
vertices relative to the origin are sheared so that the ray runs along z,
and the three 2D edge functions U, V, W of the sheared vertices decide the
hit. Watertight because:
- a vertex's sheared coordinates depend only on the vertex and the ray, so
  triangles that share it see it at the very same float32 values;
- each edge function is a*b - c*d of float32 values, computed in float64,
  where each product is exact, so its sign is the exact sign of the 2D
  orientation and a neighbour computing the shared edge the other way round
  gets exactly its negation (the paper computes them in float32 and redoes
  them in float64 where one is zero, which is as exact only where nothing
  fuses a product into the subtraction, as a GPU compiler may);
- a zero edge function counts as inside, so a ray through an edge or a
  vertex is claimed by every triangle around it. No ray from inside a closed
  mesh slips between its triangles (tests/test_triangle.py holds it to that).
Both faces are hit (no culling), so the paper's winding swap, which only
flips the signs of U, V, W and det together, is left out. det and T are
float64 too: the coordinates may reach the scene's 1e15 (camera.MAX_MAGNITUDE),
whose cubes overflow float32; t is rounded to float32 once.

A miss is (-1, 0), as sphere.py gives it; t <= 0 is behind the origin, which
the walks drop as they drop the sphere's. A triangle of zero area (a point,
a segment, a repeated vertex: its edges B - A and C - A parallel, decided on
its own vertices, not on their differences from a ray's origin, which would
round a segment into a sliver; `normal` says when that is exact) is never
hit; the loader keeps such triangles.

A hit's datum (the second value of every test): cos = |n.D|, n the plane's
unit normal (float32): the cosine between the ray and the normal, worked
out only for a ray the edges let through (a packet's from_origin works n
out once a leaf). rim is 1, so the thesis's shading, colour - (rim -
datum) / rim (shade.shade_hit), is colour - (1 - cos): the very form it
gives a sphere, whose half-chord over radius is the same cosine at its near
hit. Smooth normals do not change it; `surface`
works out the hit's barycentrics again and interpolates them for Whitted.

Why the builders' padding holds a hit (traverse.py's "same answer because"):
t = T / det = (U Az + V Bz + W Cz) / (U + V + W) with U, V, W of one sign is
a convex combination, so the ray's point at t is exactly on the triangle
whose sheared vertices are the rounded ones: each vertex moved by a few
float32 epsilons of |vertex - origin|, on every axis, whatever the angle.
pad is 2^-16 (layout.PAD, 128 epsilons) of the box's |centre|_1 plus its
half sizes, and the walks add the same of |origin|_1.

Left out: prepare_at and may_hit, the brute-force fast kernels' cull (a
sphere's cheap v > s test has no triangle twin of the same cost; a box test
would be the walk's). meets_own is False: a ray leaving a triangle never
meets that same planar triangle again.

Its WGSL twin, backends/wgpu/triangle.wgsl, has no float64: its header says
how it keeps the edge functions' signs exact in float32 and what differs.
"""

import math

import numpy as np

from ...layout import (
    NODE_COST,
    PAD,
    TRI_A,
    TRI_B,
    TRI_BLUE,
    TRI_C,
    TRI_GREEN,
    TRI_NA,
    TRI_NB,
    TRI_NC,
    TRI_RED,
    TRI_ROWS,
    TRI_SHADED_ROWS,
    TRI_SMOOTH_ROWS,
)
from ..constants import HALF, ONE, ZERO
from ..footprint import window_of_corners
from .answers import answers, footprinted_always

# The CPU walks call this kind's tests at their leaves rather than inline them
# (compiled.leaf_test): the watertight test is long, and inlined at every leaf
# site it made a mesh's first Whitted frame compile for minutes.
INLINE_TESTS = False
# The cpu's packets of primary rays (kernels/packets.py): 16x8 pixels, the
# sphere's, each leaf's triangle tested on the rows and columns of rays that
# its vertices' footprint on the frame covers (window, kernels/footprint.py): a dense mesh's
# triangles cover a pixel or two, and tested on all 128 rays they made a
# smaller packet pay (8x8 was the shape before the footprint;
# docs/triangles.md#the-cpus-packets-a-triangle-meets-the-rows-it-covers).
PACKET_SHAPE = (16, 8)
PACKET_FOOTPRINT = True
# Whitted's shadow rays a ray at a time through the 4-wide tree, not as the
# sphere's packets: under point lights (a packet of one ray each) the packets
# lost by far more than a ray at a time loses under a dense mesh's area light
# (docs/triangles.md#whitted-on-the-cpu-the-4-wide-tree-shadow-rays-alone).
SHADOW_PACKETS = False
# What a message calls a scene's primitives of this kind.
NOUN = "triangles"
# Rows of the leaf buffer (bvh's `ordered`): the three vertices.
LEAF_ROWS = TRI_ROWS
# The cpu's leaf buffer held column by column ("F": the same rows and indices, a triangle's nine
# values side by side in memory, one or two cache lines, where in rows they are nine): a mesh's
# frames faster, primary and Whitted (docs/triangles.md, "A triangle's nine values together on
# the cpu"). The GPUs' leaf buffers stay in rows, which a warp reads coalesced.
CPU_LEAF_ORDER = "F"
# What the SAH counts a node's visit, in triangles' tests, in a tree that only the cpu's packets of
# primary rays walk (the thesis's shading): twice NODE_COST, for larger leaves where the cut is
# close. A packet tests a leaf's triangle only on the rays of its window, so a triangle costs it
# less than a node: a dense mesh's frame faster, its tree smaller (docs/triangles.md, "Larger
# leaves for the cpu's packets"). Whitted's rays alone were slower
# through it, and the GPUs' walks are not measured so: their trees keep layout.NODE_COST.
PACKETS_NODE_COST = np.float32(2.0 * NODE_COST)
# What the SAH counts a node's visit in the host's tree that cuda walks (its build "host"):
# layout.NODE_COST. Larger leaves made the tree smaller but Whitted's rays far slower
# (docs/notes/mesh-memory.md; benchmarks/archive/cuda_node_cost.py sweeps it).
CUDA_NODE_COST = NODE_COST
# Rows of the scene's buffer that the shading reads at least: with the colour.
SCENE_ROWS = TRI_SHADED_ROWS
# A packed leaf copy (make's words): float64 words a triangle, nine float32 and one unused.
PACKED_WORDS = 5
# What every test returns for a miss: sphere.py's (-1, 0).
MISS = np.float32(-1.0)
_F64 = np.float64
_F32 = np.float32


def pad(cx, cy, cz, hx, hy, hz):
    """The padding of a triangle's box (layout.PAD's rule), from its
    unpadded box as a centre and half sizes: the box is grown by
    (|centre|_1 + hx + hy + hz) * PAD on every side, which bounds every
    vertex's |v|_1 as sphere.pad's r + |centre|_1 does. Python's abs, for
    numba, numba-cuda and arrays (the tests' references)."""
    return ((abs(cx) + abs(cy) + abs(cz)) + (hx + hy + hz)) * PAD


def centres(buffer):
    """The centres of the boxes of a buffer's triangles, (3, F) float32, to
    the bit extent's: (min + max) * 0.5 of each axis's three vertices."""
    out = np.empty((3, buffer.shape[1]), np.float32)
    for axis in range(3):
        a, b, c = buffer[TRI_A + axis], buffer[TRI_B + axis], buffer[TRI_C + axis]
        lo = np.minimum(np.minimum(a, b), c)
        hi = np.maximum(np.maximum(a, b), c)
        out[axis] = (lo + hi) * HALF
    return out


def shared_colour(buffer):
    """The colour that every triangle of a scene's buffer has, where it has no
    corners' normals: a column of TRI_ROWS float32, the colour in its first
    three rows, which a buffer of the vertices' rows alone keeps after its
    last triangle (layout's TRI_ROWS); None where the triangles' colours
    differ or the buffer has more rows."""
    if buffer.shape[0] != TRI_SHADED_ROWS or buffer.shape[1] == 0:
        return None
    rows = buffer[TRI_RED : TRI_BLUE + 1]
    if not all((row == row[0]).all() for row in rows):
        return None
    return colour_column(rows[:, 0])


def colour_column(colour):
    """A column of TRI_ROWS float32, the colour (red, green, blue) in its first three rows: what
    a buffer of the vertices' rows alone keeps after its last triangle, and alone, what the cpu's
    packets shade a mesh of one colour from (`colour` reads its last column)."""
    column = np.zeros((TRI_ROWS, 1), np.float32)
    column[:3, 0] = colour
    return column


def make(jit, words=None):
    """The triangle's functions compiled with `jit`: a namespace. words: a
    backend's bit cast of one float64 load into its two float32 words; with
    it the leaf tests read the tree's triangles from a packed copy, a row a
    triangle of PACKED_WORDS float64 (x, y of A; z of A, x of B; ...; z of
    C and an unused word)."""
    padding = jit(pad)

    @jit
    def read(buffer, k):
        """Triangle k of a buffer of this layout (the scene's, or the tree's
        ordered copy): (ax, ay, az, bx, by, bz, cx, cy, cz)."""
        return (
            buffer[TRI_A, k], buffer[TRI_A + 1, k], buffer[TRI_A + 2, k],
            buffer[TRI_B, k], buffer[TRI_B + 1, k], buffer[TRI_B + 2, k],
            buffer[TRI_C, k], buffer[TRI_C + 1, k], buffer[TRI_C + 2, k],
        )  # fmt: skip

    if words is None:
        read_leaf = read
    else:

        @jit
        def read_leaf(buffer, k):
            """Triangle k of the packed copy, in five float64 loads."""
            ax, ay = words(buffer[k, np.uint64(0)])
            az, bx = words(buffer[k, np.uint64(1)])
            by, bz = words(buffer[k, np.uint64(2)])
            cx, cy = words(buffer[k, np.uint64(3)])
            cz, _ = words(buffer[k, np.uint64(4)])
            return ax, ay, az, bx, by, bz, cx, cy, cz

    @jit
    def permute(x, y, z, kz):
        """(x, y, z) turned so that axis kz comes last, the other two in
        cyclic order (the paper's kx = kz + 1, ky = kx + 1, mod 3)."""
        if kz == 0:
            return y, z, x
        if kz == 1:
            return z, x, y
        return x, y, z

    @jit
    def aim(dx, dy, dz):
        """What the watertight test needs of a ray alone: kz, the axis along
        which it goes fastest (a function of the ray alone, so every
        triangle sees one shear), and the shear (sx, sy, sz) that makes the
        ray run along it. A packet works it out once a ray (hit_aimed)."""
        adx, ady, adz = abs(dx), abs(dy), abs(dz)
        kz = 0 if (adx > ady and adx > adz) else (1 if ady > adz else 2)
        px, py, pz = permute(dx, dy, dz, kz)
        return kz, px / pz, py / pz, ONE / pz

    @jit
    def sheared(a1, a2, a3, b1, b2, b3, c1, c2, c3, sx, sy, sz):
        """woop's answer from the vertices turned by the ray's kz (permute)
        and its shear (aim)."""
        # the vertices sheared so that the ray runs along z: float32, the
        # same values for a vertex in every triangle that shares it (a
        # compiler that fuses a - s * b fuses it alike for every vertex)
        a_x = a1 - sx * a3
        a_y = a2 - sy * a3
        b_x = b1 - sx * b3
        b_y = b2 - sy * b3
        c_x = c1 - sx * c3
        c_y = c2 - sy * c3
        # the edge functions, each product exact in float64: exact signs
        u = _F64(c_x) * _F64(b_y) - _F64(c_y) * _F64(b_x)
        v = _F64(a_x) * _F64(c_y) - _F64(a_y) * _F64(c_x)
        w = _F64(b_x) * _F64(a_y) - _F64(b_y) * _F64(a_x)
        zero = _F64(0.0)
        if (u < zero or v < zero or w < zero) and (u > zero or v > zero or w > zero):
            return zero, zero, zero, zero, zero
        det = u + v + w
        t = u * _F64(sz * a3) + v * _F64(sz * b3) + w * _F64(sz * c3)
        return u, v, w, t, det

    @jit
    def woop(ax, ay, az, bx, by, bz, cx, cy, cz, dx, dy, dz):
        """The watertight test of the ray from the origin along (dx, dy, dz)
        against the triangle of vertices A, B, C relative to that origin:
        (U, V, W, T) in float64, the barycentric weights of A, B and C and
        the hit's distance, all times det = U + V + W; det is 0 where the
        ray misses (outside an edge, or seeing the triangle edge on)."""
        kz, sx, sy, sz = aim(dx, dy, dz)
        a1, a2, a3 = permute(ax, ay, az, kz)
        b1, b2, b3 = permute(bx, by, bz, kz)
        c1, c2, c3 = permute(cx, cy, cz, kz)
        return sheared(a1, a2, a3, b1, b2, b3, c1, c2, c3, sx, sy, sz)

    @jit
    def normal(ax, ay, az, bx, by, bz, cx, cy, cz):
        """The plane's unit normal, N / |N| for N = (B - A) x (C - A), as
        float32; (0, 0, 0) for a triangle of zero area. The absolute
        vertices, so that a ray's origin cannot round a segment into a
        sliver; in float64, where the edges (differences of float32 values)
        are exact, so exactly parallel edges make the two products of each
        component the same real number, rounded alike: N is exactly 0 for
        any repeated vertex and for collinear vertices (whose coordinates on
        an axis are 0 or within a factor 2^28 of each other); and |N|^2 cannot
        overflow."""
        e1x, e1y, e1z = _F64(bx) - _F64(ax), _F64(by) - _F64(ay), _F64(bz) - _F64(az)
        e2x, e2y, e2z = _F64(cx) - _F64(ax), _F64(cy) - _F64(ay), _F64(cz) - _F64(az)
        nx = e1y * e2z - e1z * e2y
        ny = e1z * e2x - e1x * e2z
        nz = e1x * e2y - e1y * e2x
        nn = nx * nx + ny * ny + nz * nz
        if nn == _F64(0.0):
            return ZERO, ZERO, ZERO
        inv = _F64(1.0) / math.sqrt(nn)
        return _F32(nx * inv), _F32(ny * inv), _F32(nz * inv)

    @jit
    def finish(t, det, nx, ny, nz, dx, dy, dz):
        """A test's answer from woop's t and det and the plane's unit normal:
        (t, cos) with cos = |n.D|, or (-1, 0) where the ray misses or the
        triangle has zero area."""
        if det == _F64(0.0) or (nx == ZERO and ny == ZERO and nz == ZERO):
            return MISS, ZERO
        return _F32(t / det), abs(nx * dx + ny * dy + nz * dz)

    @jit
    def intersect(ox, oy, oz, dx, dy, dz, ax, ay, az, bx, by, bz, cx, cy, cz):
        """The ray from (ox, oy, oz) along the unit (dx, dy, dz) against the
        triangle A, B, C: (t, cos); (-1, 0) on a miss and for a triangle of
        zero area. The normal only where the edges let the ray through."""
        _, _, _, t, det = woop(
            ax - ox, ay - oy, az - oz, bx - ox, by - oy, bz - oz, cx - ox, cy - oy, cz - oz, dx, dy, dz
        )
        if det == _F64(0.0):
            return MISS, ZERO
        nx, ny, nz = normal(ax, ay, az, bx, by, bz, cx, cy, cz)
        return finish(t, det, nx, ny, nz, dx, dy, dz)

    def tests(read):
        """hit and hit_ahead on a buffer that `read` reads."""

        @jit
        def hit(buffer, k, ox, oy, oz, dx, dy, dz):
            """The closest-hit test of triangle k of a buffer: (t, cos)."""
            ax, ay, az, bx, by, bz, cx, cy, cz = read(buffer, k)
            return intersect(ox, oy, oz, dx, dy, dz, ax, ay, az, bx, by, bz, cx, cy, cz)

        @jit
        def hit_ahead(buffer, k, ox, oy, oz, dx, dy, dz, is_own):
            """The secondary rays' test: a triangle is crossed once, so hit's
            answer, but a miss for the triangle the ray leaves (is_own: the
            walks skip it anyway, as meets_own says)."""
            if is_own:
                return MISS, ZERO
            return hit(buffer, k, ox, oy, oz, dx, dy, dz)

        return hit, hit_ahead

    # on the scene's triangles (by original index), and on the tree's leaves
    hit, hit_ahead = tests(read)
    leaf_hit, leaf_hit_ahead = (hit, hit_ahead) if words is None else tests(read_leaf)

    @jit
    def seen_from(row, ox, oy, oz):
        """A leaf's row (read_leaf's) as rays from (ox, oy, oz) see it: its
        vertices relative to that origin and its plane's unit normal, worked
        out once for a packet of rays that share it (hit_from's and
        hit_ahead_from's first argument)."""
        ax, ay, az, bx, by, bz, cx, cy, cz = row
        nx, ny, nz = normal(ax, ay, az, bx, by, bz, cx, cy, cz)
        return ax - ox, ay - oy, az - oz, bx - ox, by - oy, bz - oz, cx - ox, cy - oy, cz - oz, nx, ny, nz

    @jit
    def from_origin(buffer, k, ox, oy, oz):
        """seen_from for triangle k of the tree's leaf buffer."""
        return seen_from(read_leaf(buffer, k), ox, oy, oz)

    @jit
    def hit_from(seen, dx, dy, dz):
        """leaf_hit for one ray of the packet whose origin `seen` is from:
        the very values hit computes (the same subtractions)."""
        ax, ay, az, bx, by, bz, cx, cy, cz, nx, ny, nz = seen
        _, _, _, t, det = woop(ax, ay, az, bx, by, bz, cx, cy, cz, dx, dy, dz)
        return finish(t, det, nx, ny, nz, dx, dy, dz)

    @jit
    def turned(seen, kz):
        """seen_from's answer with its vertices turned by permute for rays
        whose axis is kz (aim's): once for a packet whose rays share it."""
        ax, ay, az, bx, by, bz, cx, cy, cz, nx, ny, nz = seen
        a1, a2, a3 = permute(ax, ay, az, kz)
        b1, b2, b3 = permute(bx, by, bz, kz)
        c1, c2, c3 = permute(cx, cy, cz, kz)
        return a1, a2, a3, b1, b2, b3, c1, c2, c3, nx, ny, nz

    @jit
    def hit_aimed(seen_turned, sx, sy, sz, dx, dy, dz):
        """hit_from for a ray of the packet, from the triangle turned for its
        kz (turned) and its shear (aim): the very values hit_from computes."""
        a1, a2, a3, b1, b2, b3, c1, c2, c3, nx, ny, nz = seen_turned
        _, _, _, t, det = sheared(a1, a2, a3, b1, b2, b3, c1, c2, c3, sx, sy, sz)
        return finish(t, det, nx, ny, nz, dx, dy, dz)

    @jit
    def hit_ahead_from(seen, dx, dy, dz, is_own):
        """leaf_hit_ahead for one ray of the packet whose origin `seen` is from."""
        if is_own:
            return MISS, ZERO
        return hit_from(seen, dx, dy, dz)

    @jit
    def meets_own(own_inside):
        """Never: a ray leaving a triangle cannot meet that plane's triangle
        again, so the walks skip the triangle a ray leaves, whichever way."""
        return False

    @jit
    def box(ax, ay, az, bx, by, bz, cx, cy, cz):
        """The unpadded box as a centre and half sizes, (cx, cy, cz, hx, hy,
        hz): centre (min + max) * 0.5 per axis (centres' to the bit), half
        the larger of its distances to min and max, so centre -+ half holds
        the vertices whatever the rounding."""
        lx, ly, lz = min(min(ax, bx), cx), min(min(ay, by), cy), min(min(az, bz), cz)
        ux, uy, uz = max(max(ax, bx), cx), max(max(ay, by), cy), max(max(az, bz), cz)
        mx, my, mz = (lx + ux) * HALF, (ly + uy) * HALF, (lz + uz) * HALF
        hx = max(mx - lx, ux - mx)
        hy = max(my - ly, uy - my)
        hz = max(mz - lz, uz - mz)
        return mx, my, mz, hx, hy, hz

    @jit
    def extent(buffer, k):
        """Triangle k of the scene's buffer as the builders see it: its
        padded box as a centre and half its size on each axis, (cx, cy, cz,
        hx, hy, hz). Three half sizes, a triangle's box being no cube; the
        host SAH builder weighs its splits over the largest, the cube
        around the box, then refits the tree's boxes to `bounds`
        (bvh/sah_steps.py)."""
        return extent_of(read(buffer, k))

    @jit
    def extent_of(row):
        """extent of a triangle's nine values as `read` gives them (a mesh's
        vertices read through its faces too: kernels/primitives/triangle_mesh.py)."""
        ax, ay, az, bx, by, bz, cx, cy, cz = row
        mx, my, mz, hx, hy, hz = box(ax, ay, az, bx, by, bz, cx, cy, cz)
        p = padding(mx, my, mz, hx, hy, hz)
        return mx, my, mz, hx + p, hy + p, hz + p

    @jit
    def box_of(row):
        """A leaf's row's (read_leaf's) padded box: (lo x, y, z, hi x, y, z),
        extent's centre -+ half."""
        ax, ay, az, bx, by, bz, cx, cy, cz = row
        mx, my, mz, hx, hy, hz = box(ax, ay, az, bx, by, bz, cx, cy, cz)
        p = padding(mx, my, mz, hx, hy, hz)
        hx += p
        hy += p
        hz += p
        return mx - hx, my - hy, mz - hz, mx + hx, my + hy, mz + hz

    @jit
    def window(view, place, rows, columns, row, margin, ox, oy, oz):
        """The rays of a packet of primary rays that the triangle of a
        leaf's row can meet (kernels/footprint.py): its vertices' footprint
        (footprint.window_of_corners), each vertex moved as far as the test's
        rounding moves it (its difference from the origin and its shear, see
        above), tighter than its box's, which holds more pixels' centres. The
        origin's own rounding is in the vertices' differences, so margin,
        which the box's footprint adds for it, is not used."""
        ax, ay, az, bx, by, bz, cx, cy, cz = row
        return window_of_corners(view, place, rows, columns, ((ax, ay, az), (bx, by, bz), (cx, cy, cz)), ox, oy, oz)

    @jit
    def bounds(buffer, k):
        """Triangle k's padded box: box_of its row of the tree's leaf buffer."""
        return box_of(read_leaf(buffer, k))

    @jit
    def copy_leaf(buffer, k, leaves, at):
        """Triangle k of the scene's buffer into the tree's leaf buffer (the
        builders' `ordered`) at column `at`: its nine vertex values, never
        the normals."""
        for row in range(TRI_ROWS):
            leaves[row, at] = buffer[row, k]

    @jit
    def pack_leaf(leaves, k, rows):
        """Triangle k of the tree's leaf buffer into its row of a packed copy
        (rows: float32, 2 * PACKED_WORDS columns, which read_leaf reads
        through `words`): its nine vertex values; the tenth word is unused."""
        for c in range(LEAF_ROWS):
            rows[k, c] = leaves[c, k]

    @jit
    def surface(ox, oy, oz, dx, dy, dz, t, i, triangles):
        """The hit of a ray on triangle i at t: (point, unit normal on the
        ray's side, cos_i on that side, whether the ray meets the back face:
        N = (B - A) x (C - A) points away from it, which in a closed mesh
        wound counter-clockwise seen from outside is meeting it from within).
        Where the scene's buffer has the corners' normals (TRI_SMOOTH_ROWS),
        the normal is theirs, weighted by the hit's barycentrics (the test
        run again on the same ray) and turned to the ray's side as the plane's
        is; where that leaves it facing away from the ray (a silhouette's
        grazing hit) the plane's normal is kept."""
        px = ox + t * dx
        py = oy + t * dy
        pz = oz + t * dz
        ax, ay, az, bx, by, bz, cx, cy, cz = read(triangles, i)
        gx, gy, gz = normal(ax, ay, az, bx, by, bz, cx, cy, cz)
        cos_g = -(gx * dx + gy * dy + gz * dz)
        inside = cos_g < ZERO  # the ray meets the back face
        if inside:
            gx, gy, gz, cos_g = -gx, -gy, -gz, -cos_g
        if triangles.shape[0] < TRI_SMOOTH_ROWS:
            return px, py, pz, gx, gy, gz, cos_g, inside
        u, v, w, _, det = woop(
            ax - ox, ay - oy, az - oz, bx - ox, by - oy, bz - oz, cx - ox, cy - oy, cz - oz, dx, dy, dz
        )
        if det == _F64(0.0):
            return px, py, pz, gx, gy, gz, cos_g, inside
        wa, wb, wc = _F32(u / det), _F32(v / det), _F32(w / det)
        nx = wa * triangles[TRI_NA, i] + wb * triangles[TRI_NB, i] + wc * triangles[TRI_NC, i]
        ny = wa * triangles[TRI_NA + 1, i] + wb * triangles[TRI_NB + 1, i] + wc * triangles[TRI_NC + 1, i]
        nz = wa * triangles[TRI_NA + 2, i] + wb * triangles[TRI_NB + 2, i] + wc * triangles[TRI_NC + 2, i]
        nn = nx * nx + ny * ny + nz * nz
        if not nn > ZERO:
            return px, py, pz, gx, gy, gz, cos_g, inside
        inv_n = ONE / _F32(math.sqrt(nn))
        nx *= inv_n
        ny *= inv_n
        nz *= inv_n
        if nx * gx + ny * gy + nz * gz < ZERO:
            nx, ny, nz = -nx, -ny, -nz
        cos_i = -(nx * dx + ny * dy + nz * dz)
        if cos_i <= ZERO:
            return px, py, pz, gx, gy, gz, cos_g, inside
        return px, py, pz, nx, ny, nz, cos_i, inside

    @jit
    def colour(triangles, i):
        """Triangle i's colour (red, green, blue), the scene's buffer's
        TRI_RED..TRI_BLUE rows (meshes.mesh_leaves writes them); of a buffer
        of the vertices' rows alone, the one colour in its last column's first
        three rows (shared_colour)."""
        if triangles.shape[0] < TRI_SHADED_ROWS:
            last = triangles.shape[1] - 1
            return triangles[0, last], triangles[1, last], triangles[2, last]
        return triangles[TRI_RED, i], triangles[TRI_GREEN, i], triangles[TRI_BLUE, i]

    @jit
    def rim(triangles, i):
        """What the thesis's shading divides a hit's datum (the cosine) by:
        1, so its colour - (rim - datum) / rim is colour - (1 - cos)."""
        return ONE

    # pad: the module's pad, compiled
    footprinted = footprinted_always(jit, PACKET_FOOTPRINT)
    hit_whole = hit_from  # what the packets test an unfootprinted primitive with
    extra = ("permute", "sheared", "woop", "normal", "finish", "box", "extent_of")
    return answers("triangle", {**locals(), "pad": padding}, extra)
