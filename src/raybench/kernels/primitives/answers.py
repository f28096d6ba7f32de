"""The answers every primitive's make(jit) gives, and the namespace of them.

The builders, the walks and the shading ask a primitive only these
(kernels/primitives/__init__.py says who asks what); a kind may give more of
its own (the sphere's fast-kernel cull, the triangle's parts of its test).
Built here by name, so a kind that lacks one is named at its make, not deep
in a compile.
"""

from types import SimpleNamespace

from ..footprint import window_of

ANSWERS = (
    "read",
    "read_leaf",
    "intersect",
    "hit",
    "hit_ahead",
    "leaf_hit",
    "leaf_hit_ahead",
    "meets_own",
    "from_origin",
    "seen_from",
    "hit_from",
    "hit_ahead_from",
    "aim",
    "turned",
    "hit_aimed",
    "pad",
    "bounds",
    "extent",
    "copy_leaf",
    "pack_leaf",
    "box_of",
    "window",
    "footprinted",
    "hit_whole",
    "surface",
    "rim",
    "colour",
)


def answers(kind: str, functions: dict, extra: tuple[str, ...] = ()) -> SimpleNamespace:
    """The namespace of a primitive's compiled functions (its make's, by
    name): every one of ANSWERS and the kind's own extra ones."""
    missing = [name for name in ANSWERS + extra if name not in functions]
    if missing:
        raise TypeError(f"the {kind} primitive does not answer {', '.join(missing)}")
    return SimpleNamespace(**{name: functions[name] for name in ANSWERS + extra})


def unaimed(jit, hit_from):
    """aim, turned and hit_aimed (a packet's rays' own part of a test,
    worked out once a ray; the primitive turned once for rays that share
    their kz) for a kind whose test has no part that is the ray's alone:
    hit_aimed is hit_from, and the others give what it ignores. The cpu's
    packets take them for a kind with PACKET_FOOTPRINT
    (kernels/packets.py), whose test is the triangle's."""

    @jit
    def aim(dx, dy, dz):
        return 0, dx, dy, dz

    @jit
    def turned(seen, kz):
        return seen

    @jit
    def hit_aimed(seen, sx, sy, sz, dx, dy, dz):
        return hit_from(seen, dx, dy, dz)

    return aim, turned, hit_aimed


def boxed_window(jit, box_of):
    """window (the rays of a packet of primary rays that a leaf's primitive
    can meet: kernels/footprint.py) for a kind whose test hits only within
    its padded box (box_of): the box's footprint, footprint.window_of."""

    @jit
    def window(view, place, rows, columns, row, margin, ox, oy, oz):
        return window_of(view, place, rows, columns, box_of(row), margin, ox, oy, oz)

    return window


def footprinted_always(jit, value: bool):
    """footprinted for a kind whose every primitive is tested alike by the
    cpu's packets (its PACKET_FOOTPRINT): on its window's rays (True), or on
    all of a packet's rays once its box passes their interval test (False)."""

    @jit
    def footprinted(row):
        return value

    return footprinted
