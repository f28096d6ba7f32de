"""Spheres and triangles in one tree: a leaf that is either, by its tag.

The third kind of primitive, for a scene of both (pbrt-v4's tagged Shape):
the same answers as sphere.py and triangle.py, each of them the sphere's or
the triangle's own answer (their make(jit)), chosen by the primitive's tag.
Nothing here tests a ray against a sphere or a triangle: the two modules do,
so the walks, the builders and the shading trace a mixed scene through the
one tree without a line of their own. Why one tree with typed leaves and
not a tree per kind: docs/notes/mixed-scenes.md (measured).

Its buffers (layout's MIX_ rows, a column a primitive): a primitive's own
kind's rows from row 0 (zeros after a sphere's), and its tag in the
buffer's last row: MIX_SPHERE or MIX_TRIANGLE. The scene's buffer (scene_meshes.mixed_leaves) is at least
MIX_SCENE_ROWS rows: a triangle's shaded rows, its corners' normals where a
mesh has them (triangle.surface reads the buffer's height to know), then the
tag; the tree's leaf buffer MIX_LEAF_ROWS: the nine rows a triangle's test
reads, then the tag. A packed leaf copy (make's words) is five float64, the
ten float32 as they are: the sphere's and the triangle's readers read their
first two and five words, and the tag is the tenth float.

read gives (tag, nine rows) and seen_from (tag, twelve values): one type for
either kind (compiled code takes one type a value), the sphere's with zeros
after its own. A hit's datum is the kind's (a sphere's half-chord, a
triangle's cosine), and rim the kind's, so the thesis's shading is each
kind's. meets_own is the sphere's rule (going into it), and the triangle's
hit_ahead misses the triangle a ray leaves whatever it is told.
"""

import numpy as np

from ...layout import MIX_LEAF_ROWS, MIX_SCENE_ROWS, MIX_SPHERE, TRI_ROWS
from ..constants import ZERO
from . import sphere, triangle
from .answers import answers

# As the triangle's (compiled.leaf_test): its tests hold the triangle's.
INLINE_TESTS = False
# The cpu's packets of primary rays: the sphere's shape (the SPD's scenes were measured with it).
PACKET_SHAPE = sphere.PACKET_SHAPE
# ... and each leaf primitive tested as its kind's are (footprinted): a triangle
# on the rays of its window (kernels/footprint.py), a sphere on all that pass
# its box's interval test. Tested all as spheres, a scene of meshes among spheres
# was slower by far (docs/notes/mixed-scenes.md, "The cpu's packets: each kind's own test").
PACKET_FOOTPRINT = True
# Whitted's shadow rays as the triangle's, a ray at a time: the SPD's scenes of
# both kinds were faster so (docs/triangles.md).
SHADOW_PACKETS = triangle.SHADOW_PACKETS
# What a message calls a scene's primitives of this kind.
NOUN = "spheres and triangles"
# Rows of the leaf buffer (bvh's `ordered`): a triangle's nine, then the tag.
LEAF_ROWS = MIX_LEAF_ROWS
# The cpu's leaf buffer column by column, as the triangle's: a primitive's ten values together.
CPU_LEAF_ORDER = triangle.CPU_LEAF_ORDER
# A node's visit in the cpu's packets' tree as in every tree: layout.NODE_COST (the triangle's
# larger leaves made a mesh among spheres slower: docs/triangles.md, "Larger leaves for the cpu's
# packets").
PACKETS_NODE_COST = sphere.PACKETS_NODE_COST
CUDA_NODE_COST = sphere.CUDA_NODE_COST
# Rows of the scene's buffer that the shading reads at least: a triangle's shaded rows and the tag.
SCENE_ROWS = MIX_SCENE_ROWS
# A packed leaf copy: five float64 words, the ten float32 of a leaf's rows.
PACKED_WORDS = 5
# The builders' padding of a box given as centre and half sizes: the
# triangle's rule, which for a sphere's cube is at least the sphere's. No
# builder calls it: extent pads each kind by its own.
pad = triangle.pad
# Each primitive keeps its own colour, as a sphere does.
shared_colour = sphere.shared_colour


def centres(buffer):
    """The centres of the boxes of a buffer's primitives, (3, N) float32,
    each kind's own centres (extent's)."""
    is_sphere = buffer[buffer.shape[0] - 1] == MIX_SPHERE
    return np.where(is_sphere, sphere.centres(buffer), triangle.centres(buffer)).astype(np.float32)


def make(jit, words=None):
    """The mixed kind's functions compiled with `jit`, each calling the
    sphere's or the triangle's of the same make(jit, words). Compiled code
    calls the functions it closes over (never a namespace's attributes), so
    each kind's answer is handed to the factories below by name."""
    sph = sphere.make(jit, words)
    tri = triangle.make(jit, words)
    padding = jit(pad)
    last = np.uint64(PACKED_WORDS - 1)

    @jit
    def tag_of(buffer, k):
        """Primitive k's tag, the last row of the scene's buffer or the tree's."""
        return buffer[buffer.shape[0] - 1, k]

    def rows(tag, nine):
        """read (or read_leaf): (the tag that `tag` reads, the nine rows that
        `nine`, the triangle's reader of the same buffer, reads)."""

        @jit
        def read(buffer, k):
            r0, r1, r2, r3, r4, r5, r6, r7, r8 = nine(buffer, k)
            return tag(buffer, k), r0, r1, r2, r3, r4, r5, r6, r7, r8

        return read

    def by_tag(tag, on_sphere, on_triangle):
        """An answer of (buffer, k): the sphere's on a sphere, the triangle's
        on a triangle, by the tag that `tag` reads."""

        @jit
        def either(buffer, k):
            if tag(buffer, k) == MIX_SPHERE:
                return on_sphere(buffer, k)
            return on_triangle(buffer, k)

        return either

    def tests(tag, s_hit, s_ahead, t_hit, t_ahead):
        """hit and hit_ahead on the buffer whose tags `tag` reads: each kind's own."""

        @jit
        def hit(buffer, k, ox, oy, oz, dx, dy, dz):
            if tag(buffer, k) == MIX_SPHERE:
                return s_hit(buffer, k, ox, oy, oz, dx, dy, dz)
            return t_hit(buffer, k, ox, oy, oz, dx, dy, dz)

        @jit
        def hit_ahead(buffer, k, ox, oy, oz, dx, dy, dz, is_own):
            if tag(buffer, k) == MIX_SPHERE:
                return s_ahead(buffer, k, ox, oy, oz, dx, dy, dz, is_own)
            return t_ahead(buffer, k, ox, oy, oz, dx, dy, dz, is_own)

        return hit, hit_ahead

    # on the scene's buffer (by original index), and on the tree's leaves
    read = rows(tag_of, tri.read)
    hit, hit_ahead = tests(tag_of, sph.hit, sph.hit_ahead, tri.hit, tri.hit_ahead)
    if words is None:
        leaf_tag, read_leaf, leaf_hit, leaf_hit_ahead = tag_of, read, hit, hit_ahead
    else:

        @jit
        def leaf_tag(buffer, k):
            """Primitive k's tag in the packed copy: its tenth float32."""
            _, tag = words(buffer[k, last])
            return tag

        read_leaf = rows(leaf_tag, tri.read_leaf)
        leaf_hit, leaf_hit_ahead = tests(leaf_tag, sph.leaf_hit, sph.leaf_hit_ahead, tri.leaf_hit, tri.leaf_hit_ahead)
    extent = by_tag(tag_of, sph.extent, tri.extent)
    colour = by_tag(tag_of, sph.colour, tri.colour)
    rim = by_tag(tag_of, sph.rim, tri.rim)
    s_intersect, t_intersect = sph.intersect, tri.intersect
    s_seen_from, t_seen_from = sph.seen_from, tri.seen_from
    s_hit_from, t_hit_from = sph.hit_from, tri.hit_from
    s_ahead_from, t_ahead_from = sph.hit_ahead_from, tri.hit_ahead_from
    s_box_of, t_box_of = sph.box_of, tri.box_of
    s_copy_leaf, t_copy_leaf = sph.copy_leaf, tri.copy_leaf
    s_surface, t_surface = sph.surface, tri.surface

    @jit
    def split(row):
        """A row of read's as (tag, the sphere's row, the triangle's row)."""
        tag, r0, r1, r2, r3, r4, r5, r6, r7, r8 = row
        return tag, (r0, r1, r2, r3), (r0, r1, r2, r3, r4, r5, r6, r7, r8)

    @jit
    def intersect(ox, oy, oz, dx, dy, dz, row):
        """The ray from (ox, oy, oz) along the unit (dx, dy, dz) against a
        row of read's: the kind's own intersect. (t, datum)."""
        tag, (cx, cy, cz, r), (ax, ay, az, bx, by, bz, qx, qy, qz) = split(row)
        if tag == MIX_SPHERE:
            return s_intersect(ox, oy, oz, dx, dy, dz, cx, cy, cz, r)
        return t_intersect(ox, oy, oz, dx, dy, dz, ax, ay, az, bx, by, bz, qx, qy, qz)

    @jit
    def meets_own(own_inside):
        """The sphere's rule: a ray leaving a primitive may meet it again only
        going into it. A triangle's hit_ahead misses its own triangle anyway."""
        return own_inside

    @jit
    def seen_from(row, ox, oy, oz):
        """A row of read's as rays from (ox, oy, oz) see it: (tag, the kind's
        seen_from), a sphere's four values followed by zeros."""
        tag, a_sphere, a_triangle = split(row)
        if tag == MIX_SPHERE:
            ex, ey, ez, r = s_seen_from(a_sphere, ox, oy, oz)
            return tag, ex, ey, ez, r, ZERO, ZERO, ZERO, ZERO, ZERO, ZERO, ZERO, ZERO
        ax, ay, az, bx, by, bz, cx, cy, cz, nx, ny, nz = t_seen_from(a_triangle, ox, oy, oz)
        return tag, ax, ay, az, bx, by, bz, cx, cy, cz, nx, ny, nz

    @jit
    def from_origin(buffer, k, ox, oy, oz):
        """seen_from for primitive k of the tree's leaf buffer."""
        return seen_from(read_leaf(buffer, k), ox, oy, oz)

    @jit
    def seen_split(seen):
        """A seen_from's answer as (tag, the sphere's, the triangle's)."""
        tag, a, b, c, d, e, f, g, h, i, j, k, m = seen
        return tag, (a, b, c, d), (a, b, c, d, e, f, g, h, i, j, k, m)

    @jit
    def hit_from(seen, dx, dy, dz):
        """The kind's hit_from for one ray of the packet whose origin `seen` is from."""
        tag, by_sphere, by_triangle = seen_split(seen)
        return s_hit_from(by_sphere, dx, dy, dz) if tag == MIX_SPHERE else t_hit_from(by_triangle, dx, dy, dz)

    @jit
    def hit_ahead_from(seen, dx, dy, dz, is_own):
        """The kind's hit_ahead_from for one ray of the packet whose origin `seen` is from."""
        tag, by_sphere, by_triangle = seen_split(seen)
        if tag == MIX_SPHERE:
            return s_ahead_from(by_sphere, dx, dy, dz, is_own)
        return t_ahead_from(by_triangle, dx, dy, dz, is_own)

    @jit
    def box_of(row):
        """A row of read's padded box, the kind's: (lo x, y, z, hi x, y, z)."""
        tag, a_sphere, a_triangle = split(row)
        return s_box_of(a_sphere) if tag == MIX_SPHERE else t_box_of(a_triangle)

    @jit
    def bounds(buffer, k):
        """Primitive k's padded box: box_of its row of the tree's leaf buffer."""
        return box_of(read_leaf(buffer, k))

    @jit
    def copy_leaf(buffer, k, leaves, at):
        """Primitive k of the scene's buffer into the tree's leaf buffer at
        column `at`: the kind's copy_leaf, zeros after a sphere's rows, and the tag."""
        tag = tag_of(buffer, k)
        if tag == MIX_SPHERE:
            s_copy_leaf(buffer, k, leaves, at)
            for row in range(sphere.LEAF_ROWS, TRI_ROWS):
                leaves[row, at] = ZERO
        else:
            t_copy_leaf(buffer, k, leaves, at)
        leaves[LEAF_ROWS - 1, at] = tag

    @jit
    def pack_leaf(leaves, k, packed):
        """Primitive k of the tree's leaf buffer (or of the scene's, put in the
        tree's order: cuda's) into its row of a packed copy (float32, 2 *
        PACKED_WORDS columns): its nine values, then the tag, the buffer's last row."""
        for c in range(TRI_ROWS):
            packed[k, c] = leaves[c, k]
        packed[k, TRI_ROWS] = tag_of(leaves, k)

    @jit
    def surface(ox, oy, oz, dx, dy, dz, t, i, buffer):
        """The kind's surface at a hit on primitive i of the scene's buffer."""
        if tag_of(buffer, i) == MIX_SPHERE:
            return s_surface(ox, oy, oz, dx, dy, dz, t, i, buffer)
        return t_surface(ox, oy, oz, dx, dy, dz, t, i, buffer)

    # The cpu's packets of primary rays (kernels/packets.py) read the tag once a
    # leaf's primitive (footprinted), not once a ray: a triangle is then tested
    # on its window's rays through the triangle's own aim, turned and
    # hit_aimed, and a sphere on all the rays through the sphere's hit_from
    # (hit_whole), each loop over the rays of one kind's test alone.
    aim, t_turned, hit_aimed, t_window, s_hit_whole = tri.aim, tri.turned, tri.hit_aimed, tri.window, sph.hit_from

    @jit
    def footprinted(row):
        """Whether a row of read_leaf's is a triangle's."""
        return row[0] != MIX_SPHERE

    @jit
    def window(view, place, rows, columns, row, margin, ox, oy, oz):
        """A triangle's row's window (footprinted): its vertices'."""
        return t_window(view, place, rows, columns, split(row)[2], margin, ox, oy, oz)

    @jit
    def turned(seen, kz):
        """A triangle's seen_from (footprinted) turned for rays whose axis is kz."""
        return t_turned(seen_split(seen)[2], kz)

    @jit
    def hit_whole(seen, dx, dy, dz):
        """A sphere's seen_from (not footprinted) against one ray: the sphere's hit_from."""
        return s_hit_whole(seen_split(seen)[1], dx, dy, dz)

    return answers("mixed", {**locals(), "pad": padding}, ("tag_of", "leaf_tag"))
