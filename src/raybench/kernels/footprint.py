"""Which rays of a packet of primary rays a primitive can meet: its box (a
leaf primitive's, grown as the walk grows it; window_of) or the corners
whose hull holds it (the triangle's vertices; window_of_corners) projected
through the pinhole camera onto the frame's pixels, so that the packet's
leaf tests a primitive on the rows and columns of rays its footprint covers,
not on all (kernels/packets.py, for a kind whose PACKET_FOOTPRINT is True;
each kind's `window` answer says which).

Why: a dense mesh's triangles cover a pixel or two, and a packet's leaf
tested each of them on all of its rays, of which a row or two can meet it.

The same answer because: a primary ray's direction is Camera.basis's F + R'u
+ U'v for its pixel's (u, v), normalised (trace.primary_ray), computed in
float32, so it is parallel to that sum plus an error e of at most 8 float32
epsilons of |F_i| + |R'_i| + |U'_i| on each axis i. A point P of the box
that the ray meets (the walks' premise: a primitive's test hits only within
its padded box grown by the margin) is then s (F + R'u + U'v + e) for some s
> 0, so the inverse of the matrix [F R' U'] gives P's coordinates (a, b, c)
= s (1 + ea, u + eb, v + ec), with ea, eb, ec bounded by that matrix's rows
times e: b / a is u within (eb + |u| ea) / (1 - ea), and c / a is v within
the same with ec. Over the box, a, b and c each lie in an interval (the
rows' dot products taken at the box's planes), and for a > 0 the quotients'
extremes are at the intervals' ends. The bound is doubled, the float32
rounding of u and v themselves added, and the range widened to whole
pixels; a box that reaches to or behind the camera's plane (a <= 0) gets
every row and column. The arithmetic is float64, whose rounding is far below the
margin the walk adds to every box.
"""

import math

import numba
import numpy as np

from ..layout import W_COUNT, W_HI, W_LO, WIDTH

_F64 = np.float64
# float32's unit roundoff
_EPS = _F64(2.0**-24)
# How far a ray's computed direction may stray from its pixel's exact sum, in
# float32 epsilons of the basis's magnitudes on each axis: four roundings
# making the sum, one normalising each component, and room to spare.
_DIRECTION_EPS = _F64(8.0)
# How far a corner's test may move it (window_of_corners), in float32
# epsilons of its greatest distance from the rays' origin on an axis: the
# triangle's test moves a vertex by some five (its difference from the
# origin rounded, its shear's two roundings and the shear factor's own);
# three times that.
_CORNER_EPS = _F64(16.0) * _EPS
# A frame view that culls nothing (a singular basis): width 0.
OFF = (_F64(0.0),) * 13


@numba.njit(inline="always")
def frame_view(basis, width, height):
    """What every packet of a frame shares: the rows of the inverse of [F R'
    U'] (basis[1], basis[2], basis[3]) for a, b and c, the bounds on b / a
    and c / a about u and v, the width and the height: 13 float64, or OFF."""
    fx, fy, fz = _F64(basis[1, 0]), _F64(basis[1, 1]), _F64(basis[1, 2])
    rx, ry, rz = _F64(basis[2, 0]), _F64(basis[2, 1]), _F64(basis[2, 2])
    ux, uy, uz = _F64(basis[3, 0]), _F64(basis[3, 1]), _F64(basis[3, 2])
    # the inverse's rows: R' x U', U' x F and F x R', over det = F . (R' x U')
    ax, ay, az = ry * uz - rz * uy, rz * ux - rx * uz, rx * uy - ry * ux
    bx, by, bz = uy * fz - uz * fy, uz * fx - ux * fz, ux * fy - uy * fx
    cx, cy, cz = fy * rz - fz * ry, fz * rx - fx * rz, fx * ry - fy * rx
    det = fx * ax + fy * ay + fz * az
    if not (abs(det) > _F64(0.0) and math.isfinite(det)):
        return OFF
    ax, ay, az, bx, by, bz, cx, cy, cz = (ax / det, ay / det, az / det, bx / det, by / det, bz / det, cx / det,
                                          cy / det, cz / det)  # fmt: skip
    ex = _DIRECTION_EPS * _EPS * (abs(fx) + abs(rx) + abs(ux))
    ey = _DIRECTION_EPS * _EPS * (abs(fy) + abs(ry) + abs(uy))
    ez = _DIRECTION_EPS * _EPS * (abs(fz) + abs(rz) + abs(uz))
    ea = abs(ax) * ex + abs(ay) * ey + abs(az) * ez
    eb = abs(bx) * ex + abs(by) * ey + abs(bz) * ez
    ec = abs(cx) * ex + abs(cy) * ey + abs(cz) * ez
    if not ea < _F64(0.25):
        return OFF
    # |u|, |v| <= 1/2 for a pixel's centre; u's and v's own float32 rounding
    pad_u = _F64(2.0) * (eb + _F64(0.5) * ea) / (_F64(1.0) - ea) + _F64(4.0) * _EPS
    pad_v = _F64(2.0) * (ec + _F64(0.5) * ea) / (_F64(1.0) - ea) + _F64(4.0) * _EPS
    return (ax, ay, az, bx, by, bz, cx, cy, cz, pad_u, pad_v, _F64(width), _F64(height))


@numba.njit(inline="always")
def _span(mx, my, mz, lx, ly, lz, hx, hy, hz):
    """The interval of m . P over the box of planes (lx, ..., hz)."""
    return (
        min(mx * lx, mx * hx) + min(my * ly, my * hy) + min(mz * lz, mz * hz),
        max(mx * lx, mx * hx) + max(my * ly, my * hy) + max(mz * lz, mz * hz),
    )


@numba.njit(inline="always")
def _quotients(n_lo, n_hi, inv_lo, inv_hi):
    """The interval of n / a for n in [n_lo, n_hi] and a in [a_lo, a_hi], a_lo > 0,
    from inv_lo = 1 / a_lo and inv_hi = 1 / a_hi (a float64 rounding or two, far
    inside the bounds' doubling)."""
    return min(n_lo * inv_lo, n_lo * inv_hi), max(n_hi * inv_lo, n_hi * inv_hi)


@numba.njit(inline="always")
def window_of(view, place, rows, columns, box, margin, ox, oy, oz):
    """The rays of the packet at place, (x0, y0, last_x, last_y): its pixels'
    columns and rows (rows x columns rays, a row after another; rays past the
    frame's edge copy its last pixels, unstored), that may meet box (lo x, y,
    z, hi x, y, z) grown by margin, seen from the rays' origin (ox, oy, oz):
    (first_row, end_row, first_column, end_column) of the packet, every ray
    that can meet the box among them; first_row == end_row where none can.
    view: frame_view's."""
    ax, ay, az, bx, by, bz, cx, cy, cz = view[:9]
    if view[11] == _F64(0.0):
        return 0, rows, 0, columns
    m = _F64(margin)
    lx, ly, lz = _F64(box[0]) - m - _F64(ox), _F64(box[1]) - m - _F64(oy), _F64(box[2]) - m - _F64(oz)
    hx, hy, hz = _F64(box[3]) + m - _F64(ox), _F64(box[4]) + m - _F64(oy), _F64(box[5]) + m - _F64(oz)
    a_lo, a_hi = _span(ax, ay, az, lx, ly, lz, hx, hy, hz)
    if not a_lo > _F64(0.0):  # the box reaches the camera's plane, or behind it
        return 0, rows, 0, columns
    inv_lo, inv_hi = _F64(1.0) / a_lo, _F64(1.0) / a_hi
    n_lo, n_hi = _span(bx, by, bz, lx, ly, lz, hx, hy, hz)
    b_lo, b_hi = _quotients(n_lo, n_hi, inv_lo, inv_hi)
    n_lo, n_hi = _span(cx, cy, cz, lx, ly, lz, hx, hy, hz)
    c_lo, c_hi = _quotients(n_lo, n_hi, inv_lo, inv_hi)
    return _pixels(view, place, rows, columns, b_lo, b_hi, c_lo, c_hi)


@numba.njit(inline="always")
def _pixels(view, place, rows, columns, b_lo, b_hi, c_lo, c_hi):
    """window_of's answer from the intervals of b / a and c / a that a ray
    meeting the primitive has: the rays whose u and v lie within them, the
    view's bounds on a ray's direction added. Without a branch (every
    value worked out, one answer chosen), so that a loop over a leaf's
    primitives' windows is made SIMD (packets.packet_leaf)."""
    pad_u, pad_v, width, height = view[9], view[10], view[11], view[12]
    x0, y0, last_x, last_y = place
    # pixel x = (u + 1/2) width - 1/2, y = (1/2 - v) height - 1/2
    x_lo = (b_lo - pad_u + _F64(0.5)) * width - _F64(0.5)
    x_hi = (b_hi + pad_u + _F64(0.5)) * width - _F64(0.5)
    y_lo = (_F64(0.5) - c_hi - pad_v) * height - _F64(0.5)
    y_hi = (_F64(0.5) - c_lo + pad_v) * height - _F64(0.5)
    met = (x_hi >= _F64(x0)) & (x_lo <= _F64(last_x)) & (y_hi >= _F64(y0)) & (y_lo <= _F64(last_y))
    # clamped to the packet first, so that every conversion to an integer is in range
    first = int(math.ceil(min(max(y_lo, _F64(y0)), _F64(last_y + 1)))) - y0
    last = int(math.floor(max(min(y_hi, _F64(last_y)), _F64(y0 - 1)))) - y0
    first_column = int(math.ceil(min(max(x_lo, _F64(x0)), _F64(last_x + 1)))) - x0
    last_column = int(math.floor(max(min(x_hi, _F64(last_x)), _F64(x0 - 1)))) - x0
    met = met & (last >= first) & (last_column >= first_column)
    return (first if met else 0, last + 1 if met else 0, first_column if met else 0,
            last_column + 1 if met else 0)  # fmt: skip


@numba.njit(inline="always")
def window_of_corners(view, place, rows, columns, corners, ox, oy, oz):
    """window_of for a primitive whose test hits only within the convex hull
    of its corners ((x, y, z) each), each moved by at most _CORNER_EPS (16
    float32 epsilons) of its greatest distance from the rays' origin on an axis (the
    triangle's test: its vertices relative to the origin, rounded, and
    sheared in float32, kernels/primitives/triangle.py): the hull's own
    footprint, tighter than its box's. A hit's point is a convex combination
    of the moved corners, all in front of the camera's plane (a > 0), so its
    b / a lies between the corners' (their weights times a, normalised, make
    it a convex combination of them); a corner moved by d on each axis moves
    a by at most na d (na: the row's absolute sum) and b / a by at most (nb +
    |b / a| na) d / (a - na d), doubled where na d <= a / 2, so every
    corner's quotient is taken with that bound."""
    ax, ay, az, bx, by, bz, cx, cy, cz = view[:9]
    na, nb, nc = abs(ax) + abs(ay) + abs(az), abs(bx) + abs(by) + abs(bz), abs(cx) + abs(cy) + abs(cz)
    b_lo = c_lo = _F64(math.inf)
    b_hi = c_hi = -_F64(math.inf)
    # without a branch, as _pixels: a corner at or behind the camera's plane, once moved, or an OFF view
    # (width 0) gives every row and column
    every = view[11] == _F64(0.0)
    for x, y, z in corners:
        vx, vy, vz = _F64(x) - _F64(ox), _F64(y) - _F64(oy), _F64(z) - _F64(oz)
        d = _CORNER_EPS * max(abs(vx), abs(vy), abs(vz))
        a = ax * vx + ay * vy + az * vz
        every = every | (not a > _F64(2.0) * na * d)
        inv = _F64(1.0) / a
        qb, qc, s = (bx * vx + by * vy + bz * vz) * inv, (cx * vx + cy * vy + cz * vz) * inv, _F64(2.0) * d * inv
        eb, ec = (nb + abs(qb) * na) * s, (nc + abs(qc) * na) * s
        b_lo, b_hi = min(b_lo, qb - eb), max(b_hi, qb + eb)
        c_lo, c_hi = min(c_lo, qc - ec), max(c_hi, qc + ec)
    first, end, first_column, end_column = _pixels(view, place, rows, columns, b_lo, b_hi, c_lo, c_hi)
    return (0 if every else first, rows if every else end, 0 if every else first_column,
            columns if every else end_column)  # fmt: skip


@numba.njit(inline="always")
def tree_window(view, wide, wide_links, place, rows, columns, margin, ox, oy, oz):
    """window_of for the box around the 4-wide tree's root boxes (layout's
    wide rows, row 0): the rays of the pixels at place that can meet any
    primitive of the tree, since every hit the walk finds lies in a root box
    grown by margin. Rays outside it hit nothing: the cpu's packets of a kind
    with PACKET_FOOTPRINT colour such a packet the background's without
    making its rays (packets._bvh_packets_wide). A root without a child: no ray."""
    lx = ly = lz = np.float32(np.inf)
    hx = hy = hz = -np.float32(np.inf)
    for c in range(WIDTH):
        if wide_links[0, W_COUNT + c] != 0:
            lx, ly, lz = min(lx, wide[0, W_LO[0] + c]), min(ly, wide[0, W_LO[1] + c]), min(lz, wide[0, W_LO[2] + c])
            hx, hy, hz = max(hx, wide[0, W_HI[0] + c]), max(hy, wide[0, W_HI[1] + c]), max(hz, wide[0, W_HI[2] + c])
    if not lx <= hx:
        return 0, 0, 0, 0
    return window_of(view, place, rows, columns, (lx, ly, lz, hx, hy, hz), margin, ox, oy, oz)
