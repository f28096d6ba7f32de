"""The kinds of primitive, one module each, and the one registration of each.

The answers every kind gives are listed once, in answers.ANSWERS; a kind's
make returns them through answers.answers, which names any it lacks.

Every primitive module gives the same answers (kernels/primitives/sphere.py
is the model): LEAF_ROWS, the rows of its leaf buffer; CPU_LEAF_ORDER,
how the host's tree for the cpu holds that buffer in memory (NumPy's "C",
a row a value, or "F", a primitive's values together; the walks index it
alike, and the GPUs' trees hold it in rows); PACKETS_NODE_COST, what the
host SAH builder counts a node's visit, in the kind's tests, in a tree that
only the cpu's packets of primary rays walk (the thesis's shading; every
other tree: layout.NODE_COST); INLINE_TESTS,
whether the cpu's walks inline its tests at their leaves or call them
(compiled.leaf_test: True for a test of a few instructions); PACKET_SHAPE,
the pixels (width, height) of the cpu's packets of primary rays
(kernels/packets.py); PACKET_FOOTPRINT, whether those packets test a leaf's
primitive on the rows of rays its box's footprint on the frame covers
(kernels/footprint.py) rather than on all; SHADOW_PACKETS, whether
Whitted's packets program on the cpu traces a hit's shadow rays to a light
as a packet (kernels/shadow_packets.py) or a ray at a time; SCENE_ROWS, the
rows of its scene buffer that the shading reads; pad(...), the
builders' padding; centres(buffer), its boxes' centres on the host;
shared_colour(buffer), the colour all its primitives share where cuda
keeps it once (a column; None: each keeps its own); CUDA_NODE_COST, what
the host SAH counts a node's visit in the tree that cuda walks; and
make(jit), its functions compiled for one target: for the builders (host
SAH, cuda and the model's LBVH) extent (its padded box as a centre and half
sizes) and copy_leaf (its row of the tree's leaf buffer); for the walks
read, hit (closest hit), hit_ahead and meets_own (the secondary rays' test
and the rule for the primitive a ray leaves), the same tests on the tree's
leaf buffer (leaf_hit, leaf_hit_ahead, read_leaf), and seen from an origin
that a packet of rays shares (from_origin, hit_from, hit_ahead_from; seen_from
and box_of work from a row read once; aim, a ray's own part of the test,
worked out once a packet, and turned and hit_aimed, the primitive turned
once for rays that share their aim: the triangle's shear, and
answers.unaimed's hit_from for the others; window, the rays of such a
packet it can meet, by its footprint on the frame: kernels/footprint.py;
footprinted(row), whether those packets test it so, and hit_whole, their
test of one they do not on all the rays: a kind of both's sphere),
bounds, surface (point and
normal at a hit), rim (what the thesis's shading divides by), colour (its
red, green and blue), and for the
brute-force fast kernels prepare_at and may_hit (the sphere's alone). The
walks, the pixel programs and the CPU's packets take that namespace; none of
them names a sphere.

The kinds: sphere.py (the thesis's), and triangle.py (a mesh's triangles:
the watertight test of Woop, Benthin and Wald, nine rows of vertices a leaf,
the cosine to the plane's normal as a hit's datum, so rim is 1; no
prepare_at or may_hit; its WGSL twin backends/wgpu/triangle.wgsl), and
mixed.py (a scene of both: each leaf tagged with its kind, every answer the
sphere's or the triangle's own; its WGSL twin backends/wgpu/mixed.wgsl calls
sphere.wgsl's and triangle.wgsl's, renamed by backends/wgpu/namespace.py). The cpu and cuda compile
a kind's programs when a scene holds it (backends/cpu/kinds.py,
backends/cuda/kinds.py; cuda's wavefront reads the leaves from a packed
copy, PACKED_WORDS float64 a primitive, that pack_leaf writes); wgpu
assembles a kind's shader from its WGSL pieces (backends/wgpu/shader.py).

Adding a kind: a module beside sphere.py with the same answers, its WGSL
twins in backends/wgpu/ (sphere.wgsl for the walks and the shading,
sphere_build.wgsl for the GPU build), and a line in KINDS.
"""

from . import mixed, sphere, triangle

# name: module. A scene's primitives are of these kinds; "mixed" is a scene
# of spheres and triangles, one tree of both (each leaf tagged with its kind).
KINDS = {"sphere": sphere, "triangle": triangle, "mixed": mixed}

__all__ = ["KINDS", "mixed", "sphere", "triangle"]
