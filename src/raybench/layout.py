"""The data layouts that the scene, the builder, every kernel and the WGSL
share, by name: the rows of the sphere, material and light arrays, the
slots of Whitted shading's settings, the kinds of ray and the columns of a
BVH node. The public model (scene.py, lighting.py) and the kernels both
read them here, so the model imports no kernel.

Plain module globals (ints and float32 scalars), which is how Numba's and
numba-cuda's compiled code can read them: they are frozen into the code as
constants. The WGSL gets the same values from backends/wgpu/shader.py.
"""

import numpy as np

# ---------------------------------------------------------------- spheres
# Scene.spheres: (SPHERE_ROWS, N) float32, structure of arrays, one row a field.
CX, CY, CZ, RADIUS, RED, GREEN, BLUE = range(7)
SPHERE_ROWS = 7

# ---------------------------------------------------------------- triangles
# A mesh's triangles (meshes.mesh_leaves; kernels/primitives/triangle.py):
# a column a triangle, float32. The leaf buffer (the tree's `ordered`) is
# TRI_ROWS rows: the x, y, z rows of vertex A, then B's, then C's. The
# scene's buffer has the same nine, then the triangle's colour (TRI_RED,
# TRI_GREEN, TRI_BLUE: TRI_SHADED_ROWS in all), and where the mesh has
# vertex normals the three corners' normals after it (NA's x, y, z, then
# NB's, NC's: TRI_SMOOTH_ROWS), which only the shading reads: the walks'
# leaves stay nine rows.
TRI_A, TRI_B, TRI_C = 0, 3, 6
TRI_ROWS = 9
TRI_RED, TRI_GREEN, TRI_BLUE = 9, 10, 11
TRI_SHADED_ROWS = 12
TRI_NA, TRI_NB, TRI_NC = 12, 15, 18
TRI_SMOOTH_ROWS = 21
# On cuda, in the tree's order (backends/cuda/tree_order.py), the buffer of a mesh whose triangles
# share one colour and have no corners' normals keeps the TRI_ROWS rows alone, and after its last
# triangle columns whose first three rows hold that colour, the buffer's last among them (its rows
# rounded up to 128 bytes): a quarter of the buffer's bytes less.

# ---------------------------------------------------------------- spheres and triangles in one tree
# A scene of both kinds (kernels/primitives/mixed.py, typed leaves): a column
# a primitive, its own kind's rows from row 0 (a sphere's SPHERE_ROWS, a
# triangle's TRI_SHADED_ROWS or TRI_SMOOTH_ROWS; zeros below a sphere's), and
# in the buffer's last row its tag, MIX_SPHERE or MIX_TRIANGLE. The tree's
# leaf buffer: the TRI_ROWS rows (a sphere's four, then zeros) and the tag.
MIX_SPHERE = np.float32(0.0)
MIX_TRIANGLE = np.float32(1.0)
MIX_LEAF_ROWS = TRI_ROWS + 1
MIX_SCENE_ROWS = TRI_SHADED_ROWS + 1

# ---------------------------------------------------------------- materials
# Scene.materials: (MATERIAL_ROWS, N) float32, beside the spheres (whose
# colour rows are the diffuse colour). Only Whitted shading reads them.
SPECULAR, SHININESS, REFLECT, TRANSMIT, IOR = range(5)
MATERIAL_ROWS = 5

# ---------------------------------------------------------------- lights
# Scene.lights: (LIGHT_ROWS, L) float32. The colour rows hold colour times
# intensity; a radius of 0 is a point light, more a spherical area light.
LX, LY, LZ, LRED, LGREEN, LBLUE, LRADIUS = range(7)
LIGHT_ROWS = 7

# ---------------------------------------------------------------- Whitted's settings
# Shading.params: (PARAMS,) float32, the frame's settings (lighting.Shading
# fills it, kernels/whitted.py reads it).
P_AMBIENT = 0  # 3 floats
P_BACKGROUND = 3  # 3 floats, used where P_GRADIENT is 0
P_GRADIENT = 6  # 1: the thesis's gradient behind everything
P_DEPTH = 7
P_SAMPLES = 8  # shadow rays to an area light
P_LIGHTS = 9
PARAMS = 10
# The deepest a pixel's tree of rays may go (Shading's depth): the kernels
# size their stacks of pending rays by it (kernels/whitted.py's MAX_DEPTH).
MAX_RAY_DEPTH = 16

# ---------------------------------------------------------------- ray kinds
# The columns of a frame's ray counts (Frame.rays' keys).
PRIMARY, SHADOW, REFLECTION, REFRACTION = range(4)
KINDS = ("primary", "shadow", "reflection", "refraction")

# ---------------------------------------------------------------- BVH nodes
# nodes: (M, NODE_FLOATS) float32, one 64-byte row a node, one cache line:
# the boxes of BOTH children, so one row fetch tests two boxes; links is
# the int32 view of the same memory, whose last four columns hold the
# children's refs and counts.
NODE_FLOATS = 16
NODE_BYTES = NODE_FLOATS * 4
# A child's box starts at column CHILD_BOX[c]: lo x, y, z, then hi x, y, z.
CHILD_BOX = (0, 6)
BOX_FLOATS = 6
# links[node, REF + c] and links[node, COUNT + c] for child c in 0, 1.
REF = 12
COUNT = 14
# A child's count: INNER where ref is a node's row; else the child is a
# leaf of `count` spheres from `ref` in the ordered spheres (0: an empty
# child, whose box is inverted: lo EMPTY, hi -EMPTY).
INNER = -1
# The planes of an empty child's inverted box (only a root of under two
# spheres has one): far beyond any scene (coordinates stay under 1e15), and
# finite even divided by a direction component of TINY (kernels.traverse),
# so no walk's arithmetic on it overflows or meets inf - inf.
EMPTY = np.float32(1e18)
# Relative padding of every sphere's box, of (radius + |centre|_1); the
# walks add the same fraction of |origin|_1 (kernels.traverse). 2^-16 is
# 128 float32 epsilons: many times the few epsilons by which the exact test's
# float32 hit point can stray from the true sphere (|EO| and r scale them).
PAD = np.float32(2.0**-16)
# The tree's depth is bounded whatever the input (the builder splits by
# count where SAH would go deeper).
MAX_DEPTH = 48
# Expected cost of visiting a node (two box tests), in sphere tests; the SAH
# weighs splitting against leaving the spheres in one leaf with it (bvh's
# builders; a kind's PACKETS_NODE_COST for the tree of the cpu's packets).
NODE_COST = np.float32(2.0)
# Walk stack entries: one per level on the way down is the most a
# near-first walk keeps (each level pushes at most its far child).
STACK = MAX_DEPTH + 2

# ---------------------------------------------------------------- 4-wide BVH nodes (the CPU's)
# wide: (M, WIDE_FLOATS) float32, one 128-byte row a node (two cache lines):
# up to WIDTH children, their boxes as structure of arrays (the WIDTH low x
# planes side by side, then the low y, ..., the high z), so that one SIMD
# register holds one plane of all the node's boxes; then, in the int32 view
# (wide_links), the children's refs and counts as in the binary rows:
# INNER where ref is a wide row, else a leaf of `count` spheres from `ref`
# in the binary tree's ordered spheres. A slot without a child has count 0
# and the point box at (EMPTY, EMPTY, EMPTY), which no ray's slabs enter
# but by an exact three-way tie, and then as a leaf of no spheres.
WIDTH = 4
W_LO = (0, 4, 8)  # W_LO[axis] + c: child c's low plane on that axis
W_HI = (12, 16, 20)
W_REF = 24
W_COUNT = 28
WIDE_FLOATS = 32
# A near-first walk of the wide tree pushes at most WIDTH - 1 children a level.
WIDE_STACK = (WIDTH - 1) * MAX_DEPTH + 2
