"""What a mesh's host tree holds on a GPU beside the mesh: the meshes suite's random triangles
(bench.meshes.random_triangles, each with its own three vertices), the tree built on the host as
the cuda tracer builds it, and each of its buffers over the mesh's own bytes (float32 vertices
and int32 faces), with the scene's buffer and the frame's picture and hits at 1680x1050.

    python benchmarks/archive/tree_bytes.py 1000000

The figures: docs/triangles.md, "Memory".
"""

import sys

from raybench import bvh
from raybench.bench.meshes import random_triangles
from raybench.kernels.primitives import KINDS
from raybench.meshes import MESH_COLOUR, mesh_leaves


def main(n: int) -> None:
    mesh = random_triangles(n)
    own = mesh.vertices.nbytes + mesh.faces.nbytes
    leaves = mesh_leaves(mesh, MESH_COLOUR)
    tree = bvh.build(leaves, device="cuda", primitive=KINDS["triangle"])
    frame = 1680 * 1050 * (3 + 4)  # the picture's bytes and the hits' int32
    parts = {"scene buffer": leaves.nbytes, "leaf buffer": tree.ordered.nbytes, "order": tree.order.nbytes,
             "nodes": tree.nodes.nbytes, "picture and hits": frame}  # fmt: skip
    print(
        f"{n:,} triangles, {own:,} bytes of mesh; {tree.node_count:,} node rows "
        f"({tree.nodes.nbytes / n:.1f} bytes a triangle)"
    )
    for name, size in parts.items():
        print(f"{name:>16}: {size:>13,} bytes, {size / own:.3f}x")
    print(f"{'all':>16}: {sum(parts.values()):>13,} bytes, {sum(parts.values()) / own:.3f}x")


if __name__ == "__main__":
    main(int(sys.argv[1]) if len(sys.argv) > 1 else 1_000_000)
