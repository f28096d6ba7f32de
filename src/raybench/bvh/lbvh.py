"""The LBVH that both GPU builders build (backends/cuda/build.py in
numba-cuda, backends/wgpu/build.py in WGSL): its parameters, defined once,
with no GPU library imported.
"""

# Morton codes: 10 bits an axis.
CODE_BITS = 30
AXIS_CELLS = 1 << (CODE_BITS // 3)
# Leaves of quality "lbvh": every subtree of at most LEAF_SIZE spheres (the
# leaf-size sweep found 2 and 4 alike, 8 worse:
# docs/notes/gpu-build.md#measured-on-the-h200). "sah" cuts leaves of up
# to bvh.LEAF_MAX where the SAH says.
LEAF_SIZE = 4
# Where the leaves are cut: "sah" as the SAH says; "treelet" also rebuilds
# each row's treelet where the SAH says (cuda only); "lbvh" keeps every
# subtree of LEAF_SIZE spheres a leaf, the first GPU tree, kept to be
# measured against.
QUALITIES = ("sah", "treelet", "lbvh")
QUALITY = "sah"
# Bottom-up passes of treelets: each pass more lowers the cost less (the
# model at 100,000 spheres: 1.031, 1.026, 1.025 times the host's after 1, 2,
# 3), each a launch of the bottom-up pass and its treelets' work again.
TREELET_PASSES = 1
# A refitted tree is rebuilt once its SAH cost (Builder.read_cost) exceeds
# REFIT_LIMIT times the cost it had fresh from its build: moved spheres
# stretch its boxes, and each ray then visits more of them. In the orbits
# measured (benchmarks/gpu_build.py's refit series,
# docs/notes/gpu-build.md#measured-on-the-h200) the cost levelled
# off below this and a refit plus the walk stayed cheaper than a rebuild plus
# the walk throughout; the limit is for motion that keeps stretching the boxes.
REFIT_LIMIT = 1.3
