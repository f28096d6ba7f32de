"""The WGSL compute shader, assembled from its pieces.

The pieces port the single-source kernels (raybench.kernels) function by
function, each WGSL function named after its Python twin: common.wgsl (the
frame's bindings), sphere.wgsl (kernels/primitives/sphere.py: the only piece
that reads a sphere's geometry), shade.wgsl (kernels/shade.py), trace.wgsl
(kernels/trace.py's primary ray and pixel, the entry point), and one
nearest_hit per acceleration structure: brute.wgsl, the thesis's loop over
every sphere (trace.py's scan), and traverse.wgsl, the BVH walk of
kernels/traverse.py with its own bindings and the one slab test and walk,
with ray.wgsl beside it for a ray alone or packet.wgsl (its own entry point)
for a subgroup's rays voting as one packet. Whitted shading
adds whitted.wgsl (kernels/whitted.py), and its wavefront wavefront.wgsl
(kernels/wavefront.py). WGSL has no include: each piece uses the others'
functions, and the host concatenates them (source). A scene of both kinds
(mixed.wgsl) takes the sphere's and the triangle's pieces together, their
names given a prefix as they are put in (namespace.py). tests/test_wgsl_parity.py
runs the twins on the same inputs.
"""

from __future__ import annotations

import functools
from importlib import resources

from ... import layout, lighting
from ...kernels import traverse, wavefront, whitted
from . import namespace

ACCELS = {"bvh": "traverse.wgsl", "none": "brute.wgsl"}
PIECES = ("common.wgsl", "sphere.wgsl", "shade.wgsl", "trace.wgsl")
# What takes sphere.wgsl's place in PIECES for each kind of primitive
# (kernels/primitives' KINDS): everything the walks and the shading read of
# it. The walks, the shading and Whitted's pieces are the same for every kind.
KIND_PIECES = {
    "sphere": ("sphere.wgsl",),
    "triangle": ("triangle_box.wgsl", "triangle.wgsl"),
    "mixed": ("triangle_box.wgsl", "sphere.wgsl", "triangle.wgsl", "mixed.wgsl"),
}
# In the mixed kind's shader, the sphere's and the triangle's pieces under
# prefixes (namespace.namespaced's arguments): mixed.wgsl answers to the
# walks' names, declares the scene's row and the leaf buffer for both kinds
# (dropped here), and the kinds' readers of those buffers (replaced); one
# struct Surface, the sphere's, is the hit's of either.
RENAMED = {
    "sphere.wgsl": {"prefix": "sphere_", "kept": ("Surface",), "dropped": ("Sphere", "ordered"),
                    "replaced": ("read_sphere", "read_leaf")},
    "triangle.wgsl": {"prefix": "triangle_", "dropped": ("Facet", "Sphere", "ordered", "Surface"),
                      "replaced": ("read_leaf",)},
}  # fmt: skip
# The walk's constants, taken from their Python definitions rather than
# written again in WGSL: float32 values whose repr is exact, so the WGSL
# literal converts to the very float32 the CPU uses.
BVH_CONSTANTS = {
    "BVH_STACK": f"{layout.STACK}u",
    "BVH_INNER": f"{layout.INNER}",
    "BVH_PAD": repr(float(layout.PAD)),
    "BVH_TINY": repr(float(traverse.TINY)),
}


@functools.cache
def _piece(name: str) -> str:
    return resources.files(__package__).joinpath(name).read_text(encoding="utf-8")


# mixed.wgsl's constants: the tag of a sphere and the floats of a leaf (layout's MIX_ values),
# and its row's members before the tag, triangle.wgsl's struct Facet's (compute.py's mixed rows
# are a triangle's and the tag).
MIXED_CONSTANTS = {
    "MIXED_SPHERE_TAG": repr(float(layout.MIX_SPHERE)),
    "MIXED_LEAF_WORDS": f"{layout.MIX_LEAF_ROWS}",
    "FACET_MEMBERS": namespace.members(_piece("triangle.wgsl"), "Facet"),
}


def kind_piece(name: str, primitive: str) -> str:
    """A piece's text as a kind's shader takes it: the mixed kind's renames
    the sphere's and the triangle's (RENAMED); every other piece as it is."""
    if primitive == "mixed" and name in RENAMED:
        return namespace.namespaced(_piece(name), **RENAMED[name])
    return _piece(name)


# Whitted shading's constants, likewise; the lights and samples a frame's
# uniform buffer holds (lighting.MAX_LIGHTS, lighting.MAX_SHADOW_SAMPLES).
WHITTED_CONSTANTS = {
    "WHITTED_RAY_STACK": f"{whitted.RAY_STACK}u",
    "WHITTED_CUTOFF": repr(float(whitted.CUTOFF)),
    "WHITTED_OFFSET": repr(float(whitted.OFFSET)),
    "MAX_LIGHTS": f"{lighting.MAX_LIGHTS}u",
    "MAX_SAMPLES": f"{lighting.MAX_SHADOW_SAMPLES}u",
}

# The wavefront's (wavefront.wgsl; its state words as backends/wgpu/wavefront.py lays them out).
MAX_WAVES = whitted.MAX_DEPTH + 2
WAVEFRONT_CONSTANTS = {
    "WF_RAY_ROWS": f"{wavefront.RAY_ROWS}u",
    "WF_RAY_IDS": f"{wavefront.RAY_IDS}u",
    "WF_SHADOW_ROWS": f"{wavefront.SHADOW_ROWS}u",
    "WF_SHADOW_IDS": f"{wavefront.SHADOW_IDS}u",
    "WF_SHADOW_BASE": f"{MAX_WAVES}u",
    "WF_OVERFLOW": f"{2 * MAX_WAVES}u",
    "WF_WAVE": f"{2 * MAX_WAVES + 1}u",
    "WF_STATE": f"{2 * MAX_WAVES + 2}u",
    "WF_CLAMP": repr(float(wavefront.CLAMP)),
}

# The entry point of each walk, and of Whitted shading (either accel); the
# wavefront's entry points are wavefront.py's.
ENTRY = {"ray": "main", "packet": "main_packet", "whitted": "main_whitted"}


def source(workgroup: tuple[int, int], accel: str, walk: str = "ray", primitive: str = "sphere") -> str:
    """The whole shader for one workgroup shape (a compile-time constant in
    WGSL), acceleration structure ("bvh" or "none", checked by the caller)
    and BVH walk, or "whitted" for Whitted shading (ENTRY's keys: its entry
    point), for a kind of primitive (KIND_PIECES' keys)."""
    extra = []
    if accel == "bvh":
        # how the walk votes: a subgroup's rays together, or each ray alone
        extra = [_piece("packet.wgsl" if walk == "packet" else "ray.wgsl")]
    if walk == "whitted":
        extra += [_piece("whitted.wgsl")]
    elif walk == "wavefront":
        extra += [_piece("whitted.wgsl"), _piece("wavefront.wgsl")]
    pieces = [q for p in PIECES for q in (KIND_PIECES[primitive] if p == "sphere.wgsl" else (p,))]
    text = "\n".join([kind_piece(p, primitive) for p in pieces] + [_piece(ACCELS[accel])] + extra)
    text = text.replace("WORKGROUP_X", f"{workgroup[0]}u").replace("WORKGROUP_Y", f"{workgroup[1]}u")
    for name, value in {**BVH_CONSTANTS, **WHITTED_CONSTANTS, **WAVEFRONT_CONSTANTS, **MIXED_CONSTANTS}.items():
        text = text.replace(name, value)
    return text
