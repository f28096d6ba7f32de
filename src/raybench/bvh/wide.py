"""The 4-wide tree that the CPU walks, collapsed from the binary SAH tree.

Its rows are layout.W_* (WIDE_FLOATS float32 columns; their int32 view holds
the links), over the binary tree's ordered spheres.
"""

from __future__ import annotations

import sys

import numpy as np

from .. import compiled
from ..layout import (
    CHILD_BOX,
    COUNT,
    EMPTY,
    INNER,
    NODE_FLOATS,
    REF,
    W_COUNT,
    W_HI,
    W_LO,
    W_REF,
    WIDE_FLOATS,
    WIDE_STACK,
    WIDTH,
)
from . import oneshot
from .pages import reserve
from .sah import Bvh
from .sah_steps import WIDE, _area


@compiled.njit(nogil=True)
def _collapse(nodes, links, wide, wide_links):
    """Collapse the binary tree (nodes, links) into 4-wide rows (layout.W_*):
    each wide node takes a binary node's two children and, while it has
    fewer than WIDTH, opens its inner child of largest box surface area
    (its two children take its place), as Embree's and tinybvh's BVH4 are
    made from a binary SAH tree. Empty children (count 0) are dropped. The
    rows number the wide nodes depth first, the root first; returns how
    many rows were used."""
    # per slot of the node being made: the binary (row, column) of its box, its ref and count
    box_row = np.empty(WIDTH, np.int64)
    box_col = np.empty(WIDTH, np.int64)
    ref = np.empty(WIDTH, np.int32)
    count = np.empty(WIDTH, np.int32)
    # pending: (binary row whose children a wide row gets, that wide row)
    pending = np.empty((WIDE_STACK * 4, 2), np.int64)
    pending[0, 0], pending[0, 1] = 0, 0
    top, used = 1, 1
    while top > 0:
        top -= 1
        b, w = pending[top, 0], pending[top, 1]
        k = 0
        for c in range(2):
            if links[b, COUNT + c] != 0:
                box_row[k], box_col[k] = b, CHILD_BOX[c]
                ref[k], count[k] = links[b, REF + c], links[b, COUNT + c]
                k += 1
        while k < WIDTH:
            best, best_area = -1, np.float32(-1.0)
            for s in range(k):
                if count[s] == INNER:
                    r, c0 = box_row[s], box_col[s]
                    a = _area(nodes[r, c0], nodes[r, c0 + 1], nodes[r, c0 + 2], nodes[r, c0 + 3],
                              nodes[r, c0 + 4], nodes[r, c0 + 5])  # fmt: skip
                    if a > best_area:
                        best, best_area = s, a
            if best < 0:
                break
            inner = ref[best]
            # the opened child's children take its slot and the next free one
            # (a binary inner node has two; were one empty, it is dropped)
            k -= 1
            box_row[best], box_col[best], ref[best], count[best] = box_row[k], box_col[k], ref[k], count[k]
            for c in range(2):
                if links[inner, COUNT + c] != 0:
                    box_row[k], box_col[k] = inner, CHILD_BOX[c]
                    ref[k], count[k] = links[inner, REF + c], links[inner, COUNT + c]
                    k += 1
        for s in range(WIDTH):
            for axis in range(3):
                if s < k:
                    wide[w, W_LO[axis] + s] = nodes[box_row[s], box_col[s] + axis]
                    wide[w, W_HI[axis] + s] = nodes[box_row[s], box_col[s] + 3 + axis]
                else:
                    wide[w, W_LO[axis] + s] = EMPTY
                    wide[w, W_HI[axis] + s] = EMPTY
            if s < k and count[s] == INNER:
                wide_links[w, W_REF + s] = used
                wide_links[w, W_COUNT + s] = INNER
                pending[top, 0], pending[top, 1] = ref[s], used
                top += 1
                used += 1
            elif s < k:
                wide_links[w, W_REF + s] = ref[s]
                wide_links[w, W_COUNT + s] = count[s]
            else:
                wide_links[w, W_REF + s] = 0
                wide_links[w, W_COUNT + s] = 0
    return used


def compile_collapse() -> None:
    """Compile (or load) _collapse, outside any timing."""
    _collapse(np.zeros((1, NODE_FLOATS), np.float32), np.zeros((1, NODE_FLOATS), np.int32),
              np.zeros((1, WIDE_FLOATS), np.float32), np.zeros((1, WIDE_FLOATS), np.int32))  # fmt: skip


def collapse_in_python(tree: Bvh) -> bool:
    """Whether collapse(tree) runs _collapse as Python: for a tree of at most
    WIDE spheres within one_shot(), where it takes a few ms, less than
    loading the compiled collapse, let alone compiling it."""
    return tree.interpreted or (oneshot.active() and tree.count <= WIDE)


def collapse(tree: Bvh) -> np.ndarray:
    """The 4-wide rows (layout.WIDE_FLOATS float32 columns; the int32 view holds
    the links) of a binary tree, over the same ordered spheres (see
    collapse_in_python for the way it runs)."""
    wide = reserve(max(len(tree.nodes), 1), WIDE_FLOATS)
    code = compiled.as_python(sys.modules[__name__]) if collapse_in_python(tree) else sys.modules[__name__]
    used = code._collapse(tree.nodes, tree.links, wide, wide.view(np.int32))
    # its first rows, not a copy: a copy beside the binary tree made the
    # collapse the cpu's peak with a mesh (docs/triangles.md#memory)
    return wide[: int(used)]
