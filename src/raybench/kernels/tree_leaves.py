"""A tree's leaves as the cpu's packets of primary rays read them: the tree's
leaf buffer (bvh's `ordered`), or a mesh read through the tree's order,
(vertices, faces, order): kernels/primitives/triangle_mesh.py's leaves(), the
cpu's tree of a large painted mesh whose triangles share their vertices
(triangle_mesh.read_through), which copies none of them
(docs/triangles.md#memory). Numba picks the read by the leaves' type as it
compiles.

Made for a kind of primitive, the sphere's at import; compiled.rebound
compiles this module again for another kind (backends/cpu/kinds.py).
"""

import functools

import numba

from .primitives import sphere, triangle_mesh


@functools.cache
def _made(primitive=sphere):
    """The kind's answers, compiled as the packets compile them."""
    return primitive.make(numba.njit(inline="always", error_model="numpy"))


def _kind_constants(primitive) -> dict:
    """The rows of a leaf's primitive: the kind's LEAF_ROWS."""
    return {"LEAF_ROWS": primitive.LEAF_ROWS}


_read_leaf = _made().read_leaf
LEAF_ROWS = sphere.LEAF_ROWS
_mesh = triangle_mesh.make(numba.njit(inline="always", error_model="numpy"))
_mesh_leaf, _mesh_row = _mesh.read_leaf, _mesh.copy_row


# Not inlined by Numba (inline="always"): inlined, the frames took the wrong branch of isinstance
# (Numba 0.68), and every triangle was missed.
@numba.njit(error_model="numpy")
def leaf_row(ordered, j):
    """The tree's j-th primitive's row, as the kind's read_leaf reads it from a leaf buffer."""
    if isinstance(ordered, tuple):
        return _mesh_leaf(ordered, j)
    return _read_leaf(ordered, j)


@numba.njit(error_model="numpy")
def leaf_to_lanes(ordered, j, lanes, i):
    """The tree's j-th primitive into column i of a packet's lanes (packets.packet_leaf), as a
    leaf buffer holds it."""
    if isinstance(ordered, tuple):
        _mesh_row(ordered, j, lanes, i)
    else:
        for r in range(LEAF_ROWS):
            lanes[r, i] = ordered[r, j]
