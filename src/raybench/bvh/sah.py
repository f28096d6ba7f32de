"""The BVH's builder on the host: binned SAH over the spheres, compiled with Numba.

Top-down binned SAH (surface area heuristic).
An LBVH (Morton codes) builds faster on a GPU, but its splits fall at fixed
spatial midpoints whatever the spheres do, and for the benchmark's scenes
(spheres bunched in a view frustum, radii shrinking with the count) that gives
trees a ray walks more nodes of. Binned SAH picks, at every node, the split of
16 candidate planes per axis that minimises the expected cost of a random ray,
in O(n) per level, fast enough for a million spheres (docs/notes/gpu-build.md), and
the trace, done every frame, is what the tree must serve.
Every thread takes part from the root down: a range of many spheres is split
by all of them at once, and smaller ranges are subtrees built one per thread.

Depth is bounded by MAX_DEPTH whatever the input: where SAH splits would go
deeper, the builder splits by count (object median), and spheres whose centres
all coincide are split by count too.

The steps bin one half size a primitive, the cube around its box; over a
kind whose box is no cube (the triangle) the tree's boxes are then refitted
to the primitives' own boxes (_tighten), so the walks test tight boxes.
"""

from __future__ import annotations

import functools
import threading
import time
from dataclasses import dataclass
from types import SimpleNamespace

import numba
import numpy as np

from .. import compiled
from ..errors import RaybenchError
from ..host import usable_cores
from ..kernels.primitives import sphere, triangle_mesh
from ..layout import (
    NODE_BYTES,
    NODE_COST,
    NODE_FLOATS,
)
from . import oneshot, sah_steps, sah_wide
from .sah_steps import WIDE

# Bytes the builder holds per sphere at its peak: work arrays (the last, the
# order) and their spare set, ordered spheres, two rows of nodes and the
# packed copy.
BUILD_SPHERE_BYTES = 5 * 4 + 5 * 4 + 4 * 4 + 3 * NODE_BYTES
# Per sphere on the device after the build: nodes (at most one per sphere),
# ordered spheres, order.
DEVICE_SPHERE_BYTES = NODE_BYTES + 4 * 4 + 4
MAX_SPHERES = 2**31 - 1
_ONE_BUILD = threading.Lock()


@dataclass
class Bvh:
    nodes: np.ndarray  # (M, 16) float32
    links: np.ndarray  # (M, 16) int32 view of nodes; columns REF, COUNT used
    # (LEAF_ROWS, N) float32: the primitive's leaf rows (a sphere's cx, cy, cz, r) in leaf order; for
    # the cpu, in the memory order of the kind's CPU_LEAF_ORDER (a triangle's nine values together)
    ordered: np.ndarray
    order: np.ndarray  # (N,) int32: original index of each ordered sphere
    depth: int  # deepest node (root = 1)
    build_s: float  # seconds the build took (compiled code only, unless interpreted)
    interpreted: bool = False  # built by the builder's Python, uncompiled (one_shot)

    @property
    def count(self) -> int:
        return self.order.shape[0]

    @property
    def node_count(self) -> int:
        return self.nodes.shape[0]


def compile_builder(wide: bool = True) -> None:
    """Compile (or load from Numba's cache) the builder's one-thread way and,
    if `wide`, its way for more than WIDE spheres, so build times leave it out.
    The wide way's parallel regions are most of the builder's compile (about
    four fifths, docs/notes/startup.md#the-builder-compiled-only-where-a-scene-needs-it):
    a small scene does not pay for them."""
    spheres = np.ones((7, 9), np.float32)
    spheres[:3] = np.arange(27, dtype=np.float32).reshape(3, 9) % 5
    build(spheres, threads=1, _timed=False)
    compiled.mark_ready(oneshot.READY)
    if wide:
        build(spheres, threads=1, _timed=False, _wide=2)


def _build_narrow(code, items, n, node_cost=NODE_COST):
    """The one-thread way's tree of the n primitives of items: (nodes, order, depth).
    code: sah_steps, or sah_steps as plain Python (_python_steps) to run it
    uncompiled; node_cost: _grow's."""
    p = sah_steps.work_arrays(n)
    order = p[4]
    # IEEE arithmetic, as compiled code's: no NumPy warnings on inf or nan when uncompiled
    with np.errstate(all="ignore"):
        code._prepare(items, p, 0, n, np.empty(12, np.float32))
        nodes = np.empty((2 * max(n, 1), NODE_FLOATS), np.float32)
        stack = code._stack()
        links = nodes.view(np.int32)
        top = code._root(p, nodes, links, stack)
        used, depth = code._grow(p, nodes, links, stack, top, 1, np.float32(node_cost))
    return nodes[:used].copy(), order, depth


def _read_through(primitive, items) -> bool:
    """Whether the kind reads these items through the tree's order, copying none: its
    read_through (kernels/primitives/triangle_mesh.py's, for a large mesh that shares its
    vertices)."""
    return hasattr(primitive, "read_through") and primitive.read_through(items)


def _narrow_leaf_buffer(code, items, order, leaf_rows: int, memory: str) -> np.ndarray:
    """The one-thread way's leaf buffer (sah_wide.leaf_buffer's, by code's _leaves)."""
    ordered = np.empty((leaf_rows, order.shape[0]), np.float32, order=memory)
    code._leaves(items, order, 0, order.shape[0], ordered)
    return ordered


def _python_steps():
    """sah_steps as the plain Python it was written in, the primitive's
    answers too: the same tree, compiling nothing (oneshot.one_shot)."""
    answers = sphere.make(lambda f: f)
    return compiled.as_python(sah_steps, _extent=answers.extent, _copy_leaf=answers.copy_leaf, _bounds=answers.bounds)


@functools.cache
def _steps(primitive) -> SimpleNamespace:
    """The builder's compiled steps for a kind of primitive (a module of
    kernels/primitives), by module: sah_steps and sah_wide themselves for
    the sphere, compiled at import; for another kind their copies compiled
    over its extent and copy_leaf (compiled.rebound), so each kind has its
    own and none is switched."""
    if primitive is sphere:
        return SimpleNamespace(sah_steps=sah_steps, sah_wide=sah_wide)
    return SimpleNamespace(**compiled.rebound((sah_steps, sah_wide), primitive))


def _tighten(steps, primitive, nodes, ordered) -> None:
    """The tree's boxes refitted to its leaves' own boxes (sah_steps._refit),
    for a kind whose boxes are not cubes: the steps bin and bound one half
    size a primitive, the cube around its box. The sphere's box is that
    cube, so its tree is left as built, to the bit."""
    if primitive is not sphere:
        steps.sah_steps._refit(nodes, nodes.view(np.int32), ordered)


def _items(primitives):
    """What the builder's steps read through the kind's extent and copy_leaf: a scene buffer,
    C-contiguous; or a mesh's (vertices, faces), C-contiguous each, which
    kernels/primitives/triangle_mesh.py reads."""
    if isinstance(primitives, tuple):
        return tuple(np.ascontiguousarray(a) for a in primitives)
    return np.ascontiguousarray(primitives)


def _count(items) -> int:
    """The primitives of _items' answer: a buffer's columns, a mesh's faces."""
    return triangle_mesh.count(items) if isinstance(items, tuple) else items.shape[1]


def _first(items, n: int):
    """The first n (at most) primitives of _items' answer (build makes them contiguous)."""
    return triangle_mesh.first(items, n) if isinstance(items, tuple) else items[:, :n]


def _compile_kind(items, primitive, wide: bool, device: str, through: bool) -> None:
    """Compile a kind's steps other than the sphere's (compile_builder's
    work) by building over a few of its own primitives, untimed, for the
    device's leaf buffer (its order in memory is part of the compiled type);
    through: the items are read through the tree's order (_read_through)."""
    few = _first(items, 9)
    built = build(few, threads=1, device=device, _timed=False, primitive=primitive)
    if through:  # its boxes refitted over the mesh read through the order
        nodes = built.nodes.copy()
        _steps(primitive).sah_steps._refit(nodes, nodes.view(np.int32), primitive.leaves(few, built.order))
    if wide:
        build(few, threads=1, device=device, _timed=False, _wide=2, primitive=primitive)


def build(
    spheres: np.ndarray,
    threads: int | None = None,
    device: str = "cpu",
    _timed: bool = True,
    _wide: int = WIDE,
    primitive=sphere,
    node_cost=NODE_COST,
) -> Bvh:
    """The BVH of a (7, N) float32 sphere array (Scene.spheres), or of
    another primitive's scene buffer (primitive: its module of
    kernels/primitives, meshes.mesh_leaves' for the triangle), or of a
    mesh's (vertices, faces) with primitive triangle_mesh, built on
    `threads` threads (default: all cores). Up to `_wide` spheres, on one
    thread; above, the top of the tree is split by all threads together, the
    subtrees below on one thread each. The tree is the same on any number of
    threads. device: the one whose walks the tree is for ("cpu", "cuda",
    "wgpu"). Within oneshot.one_shot(), a scene of up to `_wide` spheres may be built
    by the builder's uncompiled Python, the same tree (Bvh.interpreted).
    node_cost: what the SAH counts a node's visit, in primitives' tests
    (a kind's PACKETS_NODE_COST for the cpu's packets' tree)."""
    items = _items(spheres)
    n = _count(items)
    if n > MAX_SPHERES:
        raise RaybenchError(f"bvh: at most {MAX_SPHERES:,} spheres, got {n:,}")
    threads = threads or usable_cores()
    through = _read_through(primitive, items)  # no leaf buffer: the items read through the tree's order
    home = primitive is sphere  # the one-shot ways (plain Python, a child compiling) are the sphere's
    interpret, elsewhere = oneshot.in_python(n, _wide, device) if _timed and home else (False, False)
    oneshot.note_build(interpret)
    if elsewhere:
        oneshot.compile_elsewhere()
    elif _timed and not interpret:
        if home:
            compile_builder(wide=n > _wide)
        else:
            _compile_kind(items, primitive, n > _wide, device, through)
    steps = _steps(primitive)
    memory = primitive.CPU_LEAF_ORDER if device == "cpu" else "C"  # as the device's walks read it best
    start = time.perf_counter()
    if n > _wide:
        # Numba's threads are at most its pool's (the cores); the slicing into
        # parts follows `threads` all the same. Its default threading layer
        # cannot run two parallel regions at once: one build at a time.
        with _ONE_BUILD:
            before = numba.get_num_threads()
            numba.set_num_threads(min(threads, numba.config.NUMBA_NUM_THREADS))
            try:
                nodes, order, depth = steps.sah_wide._build_wide(items, n, threads, _wide, node_cost)
                # made once the builder's arrays are gone, so that it never adds to their peak
                if not through:
                    ordered = steps.sah_wide.leaf_buffer(items, order, primitive.LEAF_ROWS, threads, memory)
            finally:
                numba.set_num_threads(before)
    else:
        code = _python_steps() if interpret else steps.sah_steps
        nodes, order, depth = _build_narrow(code, items, n, node_cost)
        if not through:
            ordered = _narrow_leaf_buffer(code, items, order, primitive.LEAF_ROWS, memory)
    if through:
        ordered = primitive.leaves(items, order)
    elif hasattr(primitive, "COPIED_AS"):  # the leaf buffer another kind's
        primitive, steps = primitive.COPIED_AS, _steps(primitive.COPIED_AS)
    _tighten(steps, primitive, nodes, ordered)
    build_s = time.perf_counter() - start
    return Bvh(
        nodes=nodes,
        links=nodes.view(np.int32),
        ordered=ordered,
        order=order,
        depth=int(depth),
        build_s=build_s,
        interpreted=interpret,
    )
