"""One ray through the CPU's 4-wide tree (bvh.collapse): the bounces of
Whitted's rays, which leave no shared origin to make a packet of. A node's
four boxes are tested at once; the answer is traverse.walk's, ray by ray.
"""

import numba
import numpy as np

from .. import compiled
from ..layout import (
    INNER,
    PAD,
    W_COUNT,
    W_REF,
    WIDTH,
)
from .constants import ZERO
from .packet_boxes import _U, HI_X, HI_Y, HI_Z, LO_X, LO_Y, LO_Z
from .packets import _inverse, _leaf_hit_ahead, _meets_own


@numba.njit(inline="always", error_model="numpy")
def _ray_box(w, c, lx, ly, lz, hx, hy, hz, ix, iy, iz, closest):
    """traverse.slab's test of one ray on child box c of wide row w (lx =
    origin + margin, hx = origin - margin: the box grown by the margin, as
    traverse.axis_setup's, which gives them times 1/d for the GPU's fused
    multiply-add; a CPU without it gains nothing from that form): (whether
    it enters no farther than closest, where it enters)."""
    a0 = (w[_U(LO_X) + c] - lx) * ix
    a1 = (w[_U(LO_Y) + c] - ly) * iy
    a2 = (w[_U(LO_Z) + c] - lz) * iz
    b0 = (w[_U(HI_X) + c] - hx) * ix
    b1 = (w[_U(HI_Y) + c] - hy) * iy
    b2 = (w[_U(HI_Z) + c] - hz) * iz
    near = max(min(a0, b0), max(min(a1, b1), min(a2, b2)))
    far = min(max(a0, b0), min(max(a1, b1), max(a2, b2)))
    return (near <= far) & (far > ZERO) & (near <= closest), near


@numba.njit(inline="always", error_model="numpy")
def _ray_boxes(wide, row, lx, ly, lz, hx, hy, hz, ix, iy, iz, closest):
    """_ray_box on a wide node's four boxes, written out as four like
    computations that LLVM's SLP vectoriser can put in one register: (a bit
    set for each box entered, the four entry distances)."""
    w = wide[row]
    k0, n0 = _ray_box(w, _U(0), lx, ly, lz, hx, hy, hz, ix, iy, iz, closest)
    k1, n1 = _ray_box(w, _U(1), lx, ly, lz, hx, hy, hz, ix, iy, iz, closest)
    k2, n2 = _ray_box(w, _U(2), lx, ly, lz, hx, hy, hz, ix, iy, iz, closest)
    k3, n3 = _ray_box(w, _U(3), lx, ly, lz, hx, hy, hz, ix, iy, iz, closest)
    mask = np.int64(k0) | (np.int64(k1) << 1) | (np.int64(k2) << 2) | (np.int64(k3) << 3)
    return mask, (n0, n1, n2, n3)


@compiled.leaf_test(error_model="numpy")
def _wide_leaf(ordered, order, first, count, own, own_inside, ox, oy, oz, dx, dy, dz, hit, closest, hit_d):
    """A leaf's primitives against one ray (_walk_wide): the nearer hit of
    theirs and (hit, closest, hit_d), ties to the smaller original index,
    the primitive `own` the ray leaves skipped unless it can meet it again."""
    for j in range(_U(first), _U(first + count)):
        original = order[j]
        if original == own and not _meets_own(own_inside):
            continue
        t, d = _leaf_hit_ahead(ordered, j, ox, oy, oz, dx, dy, dz, original == own)
        if t > ZERO and (t < closest or (t == closest and original < hit)):
            closest = t
            hit = np.int64(original)
            hit_d = d
    return hit, closest, hit_d


@numba.njit(inline="always", error_model="numpy")
def _walk_wide(ox, oy, oz, dx, dy, dz, t_max, any_hit, own, own_inside, wide, wide_links, ordered, order, s_ref,
               s_count, s_t):  # fmt: skip
    """traverse.walk's answer for one Whitted ray (its `ahead` test, the
    sphere `own` skipped or met at its far root) through the 4-wide tree: a
    node's four boxes tested at once (_ray_boxes), the children it enters
    pushed farthest first with where the ray enters each, popped nearest
    first and skipped once a hit is nearer. The nearest sphere with 0 < t <
    t_max, ties to the smaller original index, or with any_hit the first
    found: the same (index, t, d) as the binary tree's walk, whose boxes
    are the same padded ones, as no order of visiting changes which sphere
    is nearest. s_ref, s_count, s_t: the stack (layout.WIDE_STACK)."""
    ix, iy, iz = _inverse(dx), _inverse(dy), _inverse(dz)
    margin = (abs(ox) + abs(oy) + abs(oz)) * PAD
    lx, ly, lz = ox + margin, oy + margin, oz + margin
    hx, hy, hz = ox - margin, oy - margin, oz - margin
    closest = t_max
    hit = np.int64(-1)
    hit_d = ZERO
    s_ref[0] = 0
    s_count[0] = INNER
    s_t[0] = ZERO
    top = 1
    while top > 0:
        top -= 1
        if s_t[top] > closest:
            continue
        node = s_ref[top]
        if s_count[top] != INNER:
            hit, closest, hit_d = _wide_leaf(ordered, order, node, s_count[top], own, own_inside, ox, oy, oz, dx, dy,
                                             dz, hit, closest, hit_d)  # fmt: skip
            if any_hit and hit >= 0:
                return hit, closest, hit_d
            continue
        mask, nears = _ray_boxes(wide, node, lx, ly, lz, hx, hy, hz, ix, iy, iz, closest)
        base = top
        for c in range(WIDTH):
            if not (mask >> c) & 1:
                continue
            near = nears[c]
            j = top  # insertion among this node's children, the nearest on top
            while j > base and s_t[j - 1] < near:
                s_ref[j] = s_ref[j - 1]
                s_count[j] = s_count[j - 1]
                s_t[j] = s_t[j - 1]
                j -= 1
            s_ref[j] = wide_links[node, W_REF + c]
            s_count[j] = wide_links[node, W_COUNT + c]
            s_t[j] = near
            top += 1
    return hit, closest, hit_d
