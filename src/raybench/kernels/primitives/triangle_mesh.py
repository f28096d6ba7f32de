"""The triangle as the cpu reads it from a mesh's own arrays.

Not a kind of primitive that a scene holds (KINDS): the same triangles as
triangle.py's, read through the mesh's faces, (vertices (V, 3) float32,
faces (F, 3) int32) in place of its scene buffer. The cpu's tree for the
thesis's packets is built from it (backends/cpu/tracer.py), so no scene
buffer is made; and a large mesh that shares its vertices (read_through)
has no leaf buffer either: its leaves are the mesh read through the tree's
order (leaves()), so it is held once (docs/triangles.md#memory).

Its extent is the triangle's own, given the nine values that `read` takes
from the mesh: the very float32 values that meshes.mesh_leaves copies into
a scene buffer, so the tree and its order are the scene buffer's to the bit,
and read_leaf gives what its leaf buffer holds (tests/test_triangle_mesh.py).
Compiled for the host alone: the GPUs build over the scene buffer.
"""

from types import SimpleNamespace

from ...layout import TRI_A, TRI_B, TRI_C
from . import triangle

# What bvh/sah.py asks of the kind whose tree it builds: the triangle's.
LEAF_ROWS = triangle.LEAF_ROWS
CPU_LEAF_ORDER = triangle.CPU_LEAF_ORDER
INLINE_TESTS = triangle.INLINE_TESTS
NOUN = triangle.NOUN
# Where the builder copies the triangles into a leaf buffer (not read_through), it is this kind's:
# its boxes are refitted over it, and the walks read it, as the triangle's.
COPIED_AS = triangle


def count(mesh) -> int:
    """The triangles of a (vertices, faces) pair."""
    return mesh[1].shape[0]


def first(mesh, n: int):
    """The pair of its first n triangles."""
    return mesh[0], mesh[1][:n]


# The triangles from which a mesh that shares its vertices is read through the tree's order (leaves()):
# below, its leaf buffer costs a machine little, and the packets read it faster; above, the memory
# it saves counts for more than the frame's few per cent (docs/notes/mesh-memory.md).
INDEXED_FROM = 1 << 22


def read_through(mesh) -> bool:
    """Whether the tree's leaves over a (vertices, faces) pair are the mesh read through the
    tree's order (leaves()), nothing copied: at least INDEXED_FROM triangles that share their
    vertices (fewer than two a triangle). Else the builder copies them into a leaf buffer
    (copy_leaf), which the packets read faster, and which for triangles that each have their own
    vertices is smaller than the mesh (36 bytes a triangle against 48; docs/triangles.md#memory)."""
    vertices, faces = mesh
    return faces.shape[0] >= INDEXED_FROM and vertices.shape[0] < 2 * faces.shape[0]


def leaves(mesh, order):
    """The tree's leaves over a (vertices, faces) pair read through its order: the pair and the
    order, through which read_leaf reads the tree's j-th triangle."""
    return mesh[0], mesh[1], order


def make(jit):
    """The builder's answers (extent and copy_leaf over a (vertices, faces) pair, bounds over
    its leaves()) and the packets' (read_leaf, copy_row over its leaves()), compiled with
    `jit`: the host's, so numba.njit's."""
    own = triangle.make(jit)
    extent_of, box_of = own.extent_of, own.box_of

    @jit
    def read(mesh, k):
        """Triangle k of the mesh: (ax, ay, az, bx, by, bz, cx, cy, cz), as triangle.read gives
        it from a scene buffer."""
        vertices, faces = mesh
        a, b, c = faces[k, 0], faces[k, 1], faces[k, 2]
        return (
            vertices[a, 0], vertices[a, 1], vertices[a, 2],
            vertices[b, 0], vertices[b, 1], vertices[b, 2],
            vertices[c, 0], vertices[c, 1], vertices[c, 2],
        )  # fmt: skip

    @jit
    def extent(mesh, k):
        return extent_of(read(mesh, k))

    @jit
    def copy_leaf(mesh, k, leaves, at):
        """Triangle k into the tree's leaf buffer at column `at`: its corners' x, y, z into the
        rows from layout's TRI_A, TRI_B and TRI_C, as triangle.copy_leaf copies a scene
        buffer's."""
        vertices, faces = mesh
        for corner, row in enumerate((TRI_A, TRI_B, TRI_C)):
            v = faces[k, corner]
            for axis in range(3):
                leaves[row + axis, at] = vertices[v, axis]

    @jit
    def read_leaf(leaves, j):
        """The tree's j-th triangle, of leaves(): triangle order[j] of the mesh, as
        triangle.read_leaf gives it from a leaf buffer."""
        vertices, faces, order = leaves
        return read((vertices, faces), order[j])

    @jit
    def copy_row(leaves, j, to, at):
        """The tree's j-th triangle, of leaves(), into column `at` of `to`: its corners' x, y, z
        into the rows from layout's TRI_A, TRI_B and TRI_C, as a leaf buffer holds it."""
        vertices, faces, order = leaves
        copy_leaf((vertices, faces), order[j], to, at)

    @jit
    def bounds(leaves, j):
        """The tree's j-th triangle's padded box, as triangle.bounds gives it from a leaf buffer."""
        return box_of(read_leaf(leaves, j))

    return SimpleNamespace(
        read=read, read_leaf=read_leaf, copy_row=copy_row, extent=extent, copy_leaf=copy_leaf, bounds=bounds
    )
