"""The answers every primitive's make(jit) gives, and the namespace of them.

The builders, the walks and the shading ask a primitive only these
(kernels/primitives/__init__.py says who asks what); a kind may give more of
its own (the sphere's fast-kernel cull, the triangle's parts of its test).
Built here by name, so a kind that lacks one is named at its make, not deep
in a compile.
"""

from types import SimpleNamespace

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
    "pad",
    "bounds",
    "extent",
    "copy_leaf",
    "pack_leaf",
    "box_of",
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
