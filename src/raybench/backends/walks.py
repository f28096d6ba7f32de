"""The GPU backends' two BVH walks: a ray at a time (kernels.traverse, the
CPU's code), or a group of pixels' rays as one packet, which visits a node
if any of its rays enters it (cuda: a block's rays, voting with its
barriers; wgpu: a subgroup's, voting with subgroup operations). Each backend
says which it takes by default."""

from __future__ import annotations

from ..errors import RaybenchError, shown

WALKS = ("ray", "packet")


def check_walk(walk, accel: str) -> str | None:
    if walk is None:
        return None
    if accel != "bvh":
        raise RaybenchError("walk: applies to the BVH walk only (accel='bvh'), not to brute force")
    if walk not in WALKS:
        raise RaybenchError(f"walk: must be one of {', '.join(WALKS)}, got {shown(walk)}")
    return walk
