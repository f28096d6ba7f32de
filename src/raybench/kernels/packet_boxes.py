"""A packet's box tests that hold for every kind of primitive
(kernels/packets.py's walks): the interval test of a box for all the
packet's rays at once (Wald, Boulos and Shirley 2007), on one box
(missed_by_all) or on a wide node's four (wide_mask), and a child's planes
relative to the rays' origin (wide_planes). Nothing here reads a primitive
or a packet's shape, so compiled.rebound leaves it alone, as it leaves
kernels/footprint.py.
"""

import numba
import numpy as np

from ..layout import W_HI, W_LO, WIDTH
from .constants import ZERO

# Pixels and arrays are indexed with unsigned integers: a signed index
# carries Python's negative-index wraparound, a select per lane that LLVM
# turns into gathers (docs/notes/floors.md#each-version-against-the-floor).
_U = np.uint64


# The wide rows' plane columns by axis (layout.W_LO, W_HI), as plain ints: read
# as compile-time constants, as literal offsets were.
LO_X, LO_Y, LO_Z = W_LO
HI_X, HI_Y, HI_Z = W_HI


@numba.njit(inline="always", error_model="numpy")
def missed_by_all(lx, ly, lz, hx, hy, hz, spread):
    """Whether no ray of the packet enters the box (planes relative to the
    rays' origin) nearer than its closest hit, by one test for them all
    (interval arithmetic, as in Wald, Boulos and Shirley 2007): each ray's
    inverse direction lies within spread's ranges, so its entry is no nearer,
    and its exit no farther, than bounds taken at the ranges' ends
    (min(l * i, h * i) is concave in i, max(l * i, h * i) convex). Rounding
    is monotonic, so the bounds hold for the float32 products a ray's own
    box test computes: True only where that test fails for every ray."""
    x0, x1, y0, y1, z0, z1 = spread[0], spread[1], spread[2], spread[3], spread[4], spread[5]
    near = max(
        min(min(lx * x0, hx * x0), min(lx * x1, hx * x1)),
        max(min(min(ly * y0, hy * y0), min(ly * y1, hy * y1)), min(min(lz * z0, hz * z0), min(lz * z1, hz * z1))),
    )
    far = min(
        max(max(lx * x0, hx * x0), max(lx * x1, hx * x1)),
        min(max(max(ly * y0, hy * y0), max(ly * y1, hy * y1)), max(max(lz * z0, hz * z0), max(lz * z1, hz * z1))),
    )
    # one branch where it is used, not three (`or` would branch on each, and
    # they mispredict: docs/notes/bvh-walk.md)
    return (near > far) | (far <= ZERO) | (near > spread[6])


@numba.njit(inline="always", error_model="numpy")
def wide_mask(wide, row, ox, oy, oz, margin, spread):
    """The interval test for the whole packet (missed_by_all) on all WIDTH boxes of a wide node at
    once: a bit set for each box that the interval test for the whole
    packet (missed_by_all's arithmetic) does not rule out. One loop over
    the boxes, without branches, on planes stored side by side (layout.W_LO,
    W_HI), that only reads memory and ORs the bits together: LLVM makes it
    SIMD, the four boxes in one register (vminps, vmaxps on xmm). Storing
    the planes or the outcomes to arrays in the loop kept it scalar (LLVM
    will not check a loop of 4 for overlapping arrays at run time)."""
    x0, x1, y0, y1, z0, z1, reach = spread[0], spread[1], spread[2], spread[3], spread[4], spread[5], spread[6]
    w = wide[row]
    mask = 0
    for c in range(_U(WIDTH)):
        lx = w[_U(LO_X) + c] - margin - ox
        ly = w[_U(LO_Y) + c] - margin - oy
        lz = w[_U(LO_Z) + c] - margin - oz
        hx = w[_U(HI_X) + c] + margin - ox
        hy = w[_U(HI_Y) + c] + margin - oy
        hz = w[_U(HI_Z) + c] + margin - oz
        near = max(
            min(min(lx * x0, hx * x0), min(lx * x1, hx * x1)),
            max(
                min(min(ly * y0, hy * y0), min(ly * y1, hy * y1)),
                min(min(lz * z0, hz * z0), min(lz * z1, hz * z1)),
            ),
        )
        far = min(
            max(max(lx * x0, hx * x0), max(lx * x1, hx * x1)),
            min(
                max(max(ly * y0, hy * y0), max(ly * y1, hy * y1)),
                max(max(lz * z0, hz * z0), max(lz * z1, hz * z1)),
            ),
        )
        kept = (near <= far) & (far > ZERO) & (near <= reach)
        mask |= np.int64(kept) << np.int64(c)
    return mask


@numba.njit(inline="always", error_model="numpy")
def wide_planes(wide, row, c, ox, oy, oz, margin):
    """The planes of child c of wide row `row`, its box grown by margin (as
    in kernels.traverse), relative to the packet's shared origin: (lx, ly,
    lz, hx, hy, hz), the packets' box tests' arguments (packets._rows_enter,
    shadow_packets._lanes_enter)."""
    return (
        wide[row, LO_X + c] - margin - ox,
        wide[row, LO_Y + c] - margin - oy,
        wide[row, LO_Z + c] - margin - oz,
        wide[row, HI_X + c] + margin - ox,
        wide[row, HI_Y + c] + margin - oy,
        wide[row, HI_Z + c] + margin - oz,
    )
