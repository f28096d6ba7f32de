"""The wavefront's queues fitted to a device: a frame is traced in bands of
rows, as many rows a band as queues that fit the device hold (all of them
where they fit, the common case: one band).

A pixel's rays (its primary ray, every bounce of it, its shadow rays) stay
in the band of its row, so the bands traced one after another into the same
image, hits and pixel sums give the frame traced in one piece bit for bit,
and the ray counts summed over the bands are the frame's.

Both GPU backends' wavefronts plan with plan(); each says what its queues
cost (the buffers, in bytes a ray slot, a shadow slot and a pixel of the
band) and how much its device holds.
"""

from __future__ import annotations

from dataclasses import dataclass

from ..errors import RaybenchError

# A cap on the bytes of each queue buffer, below the device's own limit; None:
# the device's. Tests lower it so that small frames are traced in bands.
QUEUE_BYTES: int | None = None


@dataclass(frozen=True)
class Buffer:
    """One buffer of the queues: its bytes are fixed + ray * ray slots +
    shadow * shadow slots + pixel * the band's pixels."""

    fixed: int = 0
    ray: int = 0
    shadow: int = 0
    pixel: int = 0

    def bytes(self, rays: int, shadows: int, pixels: int) -> int:
        return self.fixed + self.ray * rays + self.shadow * shadows + self.pixel * pixels


@dataclass(frozen=True)
class Plan:
    """Rows a band, and the queues' slots for one band of that many rows."""

    rows: int
    rays: int
    shadows: int

    def bands(self, first: int, end: int) -> list[tuple[int, int]]:
        """Rows first..end as bands (first, end) of at most self.rows rows."""
        return [(row, min(end, row + self.rows)) for row in range(first, end, self.rows)]


def capped(limit: int) -> int:
    """The device's limit, or QUEUE_BYTES where that is lower."""
    return limit if QUEUE_BYTES is None else min(limit, QUEUE_BYTES)


def grown(needed: int, capacity: int) -> int:
    """A capacity for `needed` slots: doubled until it holds them."""
    while capacity < needed:
        capacity *= 2
    return capacity


def regrown(counts, depth: int, shadow_base: int, overflow: int, rays: int, shadows: int, replan):
    """The plan to trace a frame again with, after its bands' queue counts
    (one row a band: the rays of each wave from column 0, the shadow rays of
    each from shadow_base, the overflow flag at overflow), or None where no
    queue overflowed. The queues double past what was asked of them (rays,
    shadows: the capacities now); where doubled they no longer fit even a
    row, they take only what was asked. replan(rays, shadows): a backend's
    plan for those slots, raising RaybenchError where none fits."""
    if not counts[:, overflow].any():
        return None
    need_rays = max(rays, int(counts[:, : depth + 2].max()))
    need_shadows = max(shadows, int(counts[:, shadow_base : shadow_base + depth + 1].max()))
    try:
        return replan(grown(need_rays, rays), grown(need_shadows, shadows))
    except RaybenchError:
        return replan(need_rays, need_shadows)


class Queues:
    """What both GPU backends' wavefronts do with their queues between
    frames: regrow them after a frame that overflowed them. A backend's
    Wavefront plans them (_plan(rows, rays, shadows), with plan()), makes
    them (_allocate(plan), which keeps plan, ray_capacity and
    shadow_capacity) and reads the last frame's counts back (_read_counts(): a
    row a band, as regrown() takes them, at shadow_base and overflow)."""

    depth: int
    shadow_base: int
    overflow: int
    retraced: int  # frames traced again with longer queues

    def overflowed(self) -> bool:
        """Whether the last frame's queues were too short (waits for it);
        if so they are made long enough for it (longer, or as long for
        fewer rows a band), to trace it again."""

        def replan(rays: int, shadows: int) -> Plan:
            return self._plan(self.plan.rows, rays, shadows)  # as many rows a band, if they fit

        capacity = self.ray_capacity, self.shadow_capacity
        plan = regrown(self._read_counts(), self.depth, self.shadow_base, self.overflow, *capacity, replan)
        if plan is None:
            return False
        self._allocate(plan)
        self.retraced += 1
        return True


def plan(
    width: int, rows: int, rays: int, shadows: int, buffers: list[Buffer], limit: int, least: int, holds: str
) -> Plan:
    """Queues for `rays` and `shadows` slots, what `rows` rows of `width`
    pixels need: all the rows in one band where each buffer fits in `limit`
    bytes, else as many rows a band as fit, with slots in proportion (at
    least `least` each). holds: what the limit is, for the error where not
    even one row fits ("this device's largest buffer (128 MiB)")."""

    def slots(band: int) -> tuple[int, int]:
        return max(least, -(-rays * band // rows)), max(least, -(-shadows * band // rows))

    def fits(band: int) -> bool:
        r, s = slots(band)
        return all(b.bytes(r, s, band * width) <= limit for b in buffers)

    if fits(rows):
        return Plan(rows, *slots(rows))
    # the bytes grow with the band's rows: the most rows that fit, by bisection
    band, over = 0, rows
    while over - band > 1:
        middle = (band + over) // 2
        band, over = (middle, over) if fits(middle) else (band, middle)
    if band < 1:
        r, s = slots(1)
        need = max(b.bytes(r, s, width) for b in buffers)
        raise RaybenchError(
            f"schedule 'wavefront': one row of this frame needs queues of {need / 2**20:.1f} MiB, more than "
            f"{holds}; use a narrower frame, a lower depth or schedule='pixel'"
        )
    return Plan(band, *slots(band))
