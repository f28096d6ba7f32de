"""The triangle as the host's builder reads it from a mesh's own arrays.

Not a kind of primitive that a scene holds (KINDS): the same triangles as
triangle.py's, read through the mesh's faces, (vertices (V, 3) float32,
faces (F, 3) int32) in place of its scene buffer. The cpu's tree for the
thesis's shading is built from it (backends/cpu/tracer.py), so that no
scene buffer is made beside the tree's leaf buffer: that buffer is a mesh's
triangles in the tree's order, which is all its packets read but the colour
(docs/triangles.md#memory).

Its extent is the triangle's own, given the nine values that `read` takes
from the mesh, and copy_leaf copies those nine: the very float32 values
that meshes.mesh_leaves copies into a scene buffer, so the tree, its leaf
buffer and its order are the scene buffer's to the bit
(tests/test_triangle_mesh.py). bounds reads the tree's leaf buffer, which is
the triangle's. Compiled for the host alone: the GPUs build over the scene
buffer.
"""

from types import SimpleNamespace

from ...layout import TRI_A, TRI_B, TRI_C
from . import triangle

# What bvh/sah.py asks of the kind whose tree it builds: the triangle's.
LEAF_ROWS = triangle.LEAF_ROWS
CPU_LEAF_ORDER = triangle.CPU_LEAF_ORDER
INLINE_TESTS = triangle.INLINE_TESTS
NOUN = triangle.NOUN


def count(mesh) -> int:
    """The triangles of a (vertices, faces) pair."""
    return mesh[1].shape[0]


def first(mesh, n: int):
    """The pair of its first n triangles."""
    return mesh[0], mesh[1][:n]


def make(jit):
    """The builder's answers (extent, copy_leaf, bounds) compiled with `jit`, over a
    (vertices, faces) pair: the host's, so numba.njit's."""
    own = triangle.make(jit)
    extent_of = own.extent_of

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

    return SimpleNamespace(read=read, extent=extent, copy_leaf=copy_leaf, bounds=own.bounds)
