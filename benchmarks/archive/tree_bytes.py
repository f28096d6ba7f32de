"""What a mesh's frame holds on cuda beside the mesh, counted: the meshes suite's random triangles
(bench.meshes.random_triangles, each with its own three vertices) or its icosphere (whose
triangles share their vertices), the tree built on the host as the cuda tracer builds it, and each
buffer the frame holds over the mesh's own bytes (float32 vertices and int32 faces): the scene's
buffer in the tree's order (a mesh of one colour: the vertices' nine rows, rounded up to
backends.cuda.tree_order.ROW_COLUMNS), the nodes, the tree's order, and the frame's picture and
hits at 1680x1050. It reads no GPU.

    python benchmarks/archive/tree_bytes.py random 1000000
    python benchmarks/archive/tree_bytes.py icosphere 1310720

The figures: docs/triangles.md, "Memory", and docs/notes/mesh-memory.md.
"""

import sys

from raybench import bvh, layout
from raybench.bench.meshes import icosphere, random_triangles
from raybench.kernels.primitives import KINDS
from raybench.meshes import MESH_COLOUR, mesh_leaves

ROW_COLUMNS = 32  # backends/cuda/tree_order.py's, without importing numba-cuda


def main(kind: str, n: int) -> None:
    mesh = random_triangles(n) if kind == "random" else icosphere(n)
    own = mesh.vertices.nbytes + mesh.faces.nbytes
    leaves = mesh_leaves(mesh, MESH_COLOUR)
    tree = bvh.build(leaves, device="cuda", primitive=KINDS["triangle"])
    columns = -(-(n + 1) // ROW_COLUMNS) * ROW_COLUMNS
    parts = {
        "scene buffer": layout.TRI_ROWS * columns * 4,
        "nodes": tree.nodes.nbytes,
        "order": tree.order.nbytes,
        "picture and hits": 1680 * 1050 * (3 + 4),  # the picture's bytes and the hits' int32
    }
    print(
        f"{kind} {n:,} triangles, {len(mesh.vertices):,} vertices, {own:,} bytes of mesh; "
        f"{tree.node_count:,} node rows ({tree.nodes.nbytes / n:.1f} bytes a triangle)"
    )
    for name, size in parts.items():
        print(f"{name:>16}: {size:>13,} bytes, {size / own:.3f}x")
    print(f"{'all':>16}: {sum(parts.values()):>13,} bytes, {sum(parts.values()) / own:.3f}x")


if __name__ == "__main__":
    main(sys.argv[1], int(sys.argv[2]))
