"""The bounding volume hierarchy over the spheres, one layout for every backend.

  sah      the host's builder (binned SAH, compiled with Numba): sah_steps
           splits a range and grows a subtree on one thread, sah_wide
           splits the top of a large tree with every thread
  wide     its 4-wide collapse, which the CPU walks
  oneshot  when a one-picture process runs the builder as plain Python
  lbvh     the parameters of the GPU builders' LBVH
  cost     a tree's SAH cost, whoever built it

Layout, shared by every backend (they get the same arrays; raybench.layout
names the columns):
  nodes  (M, NODE_FLOATS) float32, one 64-byte row per node, one cache line:
         the boxes of BOTH children (from CHILD_BOX[c]: lo xyz, hi xyz), so one
         row fetch tests two boxes; columns REF + c and COUNT + c hold int32
         (the `links` view of the same memory): the children's refs and counts.
           count == INNER: ref is the child node's row;
           count >= 0:     a leaf of `count` spheres from `ref` in `ordered`
                           (0: an empty child, whose box is inverted: lo EMPTY, hi -EMPTY).
  ordered (LEAF_ROWS, N) float32: the leaf buffer, each primitive's row
         (a sphere's centre and radius) in leaf order, the very float32
         values of the scene (the primitive's copy_leaf), so the exact
         test's arithmetic is the brute-force path's. A tree for the cpu
         holds it in memory as the kind's CPU_LEAF_ORDER says (a
         triangle's nine values side by side); the indices are the same.
  order  (N,) int32: the original index of each ordered sphere; hits report it.
Node 0 is the root. Every box is the union of its spheres' boxes, each sphere's
box padded by PAD (the primitive's pad) so a box never excludes a hit the exact
float32 test reports.
"""

from ..layout import NODE_COST
from .oneshot import (
    GPU_PYTHON_MAX,
    compiling_elsewhere,
    last_build_in_python,
    one_shot,
    stop_compiling_elsewhere,
    wait_for_compiling_elsewhere,
)
from .sah import BUILD_SPHERE_BYTES, DEVICE_SPHERE_BYTES, MAX_SPHERES, Bvh, build, compile_builder
from .sah_steps import LEAF_MAX, WIDE
from .wide import collapse, collapse_in_python, compile_collapse

__all__ = [
    "BUILD_SPHERE_BYTES",
    "DEVICE_SPHERE_BYTES",
    "GPU_PYTHON_MAX",
    "LEAF_MAX",
    "MAX_SPHERES",
    "NODE_COST",
    "WIDE",
    "Bvh",
    "build",
    "collapse",
    "collapse_in_python",
    "compile_builder",
    "compile_collapse",
    "compiling_elsewhere",
    "last_build_in_python",
    "one_shot",
    "stop_compiling_elsewhere",
    "wait_for_compiling_elsewhere",
]
