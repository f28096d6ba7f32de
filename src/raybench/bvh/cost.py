"""A tree's quality, measured: the SAH cost (surface area heuristic) of a BVH
in raybench.bvh's layout, whoever built it.

The expected cost of a random ray that enters the root, in sphere tests: a
ray enters a box with a chance proportional to its surface area, so

    cost = (sum over rows of NODE_COST * A(row)
            + sum over leaf children of count * A(child's box)) / A(root)

where a row's box is the union of its children's (a row visit tests both
boxes: bvh.NODE_COST sphere tests) and A is half a box's surface area. An
empty child's box is inverted (lo EMPTY, hi -EMPTY) and drops out of the
unions by min and max. The host's binned SAH builder minimises this cost
greedily with the same NODE_COST, so the costs of its trees and the GPU's
compare on the same scale.
"""

from __future__ import annotations

import numpy as np

from ..layout import CHILD_BOX, COUNT, INNER, NODE_COST, REF


def _half_area(lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    d = np.maximum(hi - lo, 0.0)
    return d[..., 0] * d[..., 1] + d[..., 1] * d[..., 2] + d[..., 2] * d[..., 0]


def sah_cost(nodes: np.ndarray) -> float:
    """The SAH cost of the tree whose rows are nodes (M, NODE_FLOATS)
    float32 (its int32 view holds the links), over the rows a walk can reach
    from the root (a builder may leave others: cuda_build's collapsed
    subtrees); 0 for a tree of no sphere."""
    if nodes.shape[0] == 0:
        return 0.0
    links = nodes.view(np.int32)
    total, root = 0.0, None
    level = np.zeros(1, np.int64)  # the reachable rows, a level at a time
    while len(level):
        boxes = [nodes[level, c : c + 6].astype(np.float64) for c in CHILD_BOX]
        rows = _half_area(np.minimum(boxes[0][:, :3], boxes[1][:, :3]), np.maximum(boxes[0][:, 3:], boxes[1][:, 3:]))
        if root is None:
            root = rows[0]
            if not root > 0:
                return 0.0
        total += float(NODE_COST) * rows.sum()
        below = []
        for slot in range(2):
            count = links[level, COUNT + slot]
            leaf = count > 0
            total += (count[leaf] * _half_area(boxes[slot][leaf, :3], boxes[slot][leaf, 3:])).sum()
            below.append(links[level, REF + slot][count == INNER])
        level = np.concatenate(below).astype(np.int64)
    return float(total / root)
