"""The triangle as the host's builder reads it from a mesh's own arrays.

Not a kind of primitive that a scene holds (KINDS): the same triangles as
triangle.py's, read through the mesh's faces, (vertices (V, 3) float32,
faces (F, 3) int32) in place of its scene buffer. The cpu's tree for the
thesis's shading is built from it (backends/cpu/tracer.py), so that no
scene buffer is made beside the tree's leaf buffer: that buffer is a mesh's
triangles in the tree's order, which is all its packets read but the colour
(docs/triangles.md#memory).

Its extent and copy_leaf are the triangle's own, given the nine values
that `read` takes from the mesh, which are the very float32 values that
meshes.mesh_leaves copies into a scene buffer: the tree, its leaf buffer and
its order are the scene buffer's to the bit (tests/test_triangle_mesh.py).
bounds reads the tree's leaf buffer, which is the triangle's.
"""

from types import SimpleNamespace

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
    (vertices, faces) pair."""
    own = triangle.make(jit)
    extent_of, put_leaf = own.extent_of, own.put_leaf

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
        put_leaf(read(mesh, k), leaves, at)

    return SimpleNamespace(read=read, extent=extent, copy_leaf=copy_leaf, bounds=own.bounds, pad=own.pad)
