"""report.md's section of the scenes suite (bench/scenes.py): each SPD scene's frames by device,
and its verdicts: how a frame's cost grows with the primitive count on each structured scene,
and what a GPU buys there; then the molecule's frames at its copies, and their verdicts: how a
frame grows with the atom count, and each GPU's lead."""

from __future__ import annotations

import math
import statistics

from .. import pictures
from ..scenes import SCENES_DEPTH
from .markdown_blocks import _table, _Writer, escape
from .numbers import fmt_ms, fmt_num, fmt_x
from .series import DEVICE_NAMES

GPUS = ("cuda", "wgpu")


def slope(points: list[tuple[int, float]]) -> float | None:
    """The least-squares slope of log(ms) against log(count): the power of the primitive count
    a frame's time grows as (1: linear, 0: flat); None under two counts."""
    points = [(n, ms) for n, ms in points if n > 0 and ms > 0]
    if len({n for n, _ in points}) < 2:
        return None
    xs = [math.log(n) for n, _ in points]
    ys = [math.log(ms) for _, ms in points]
    mx, my = sum(xs) / len(xs), sum(ys) / len(ys)
    return sum((x - mx) * (y - my) for x, y in zip(xs, ys)) / sum((x - mx) ** 2 for x in xs)


def _growth(records: list[dict], group, count, unit: str = "") -> list[str]:
    """For each group of one device's records (group(r): its name), the power of count(r) its
    frame's time grows as, and the counts it spans: "balls ^0.10 (11 to 597,872)"."""
    out = []
    for name in sorted({group(r) for r in records}):
        points = [(count(r), r["frame_ms"]["median"]) for r in records if group(r) == name]
        k = slope(points)
        if k is not None:
            out.append(f"{escape(name)} ^{k:.2f} ({min(points)[0]:,} to {max(points)[0]:,}{unit})")
    return out


def primitives(r: dict) -> int:
    """A record's primitive count as Haines counts them; a record from before triangles were
    drawn traced its spheres only, and counts those."""
    return r["options"].get("primitives", r["spheres"])


def _section_scenes(w: _Writer, label: str, slug: str, records: list[dict]) -> None:
    done = [r for r in records if r["suite"] == "scenes" and "frame_ms" in r]
    molecules = [r for r in done if "molecule" in r["options"]]
    measured = [r for r in done if "scene" in r["options"]]
    if molecules:
        _molecules(w, label, slug, molecules)
    if not measured:
        return
    measured.sort(key=lambda r: (r["device"], r["options"]["scene"].split()[0], primitives(r)))
    w(f"### {escape(label)}: real scenes", "")
    w(
        f"Haines's Standard Procedural Databases at their size factors, each with its own view, lights and fills, "
        f"Whitted shading to {SCENES_DEPTH} bounces, through the BVH: spheres, and the polygons, patches and cones "
        "as triangles, in one tree. Primitives are Haines's count of the scene; triangles, what raybench traces "
        "for its polygons and cones.",
        "",
    )
    old = sorted({r["options"]["scene"] for r in measured if r["options"].get("unrendered")})
    if old:
        w(f"Records from before triangles were drawn ({escape(', '.join(old))}) traced the spheres alone.", "")
    header = ["device", "scene", "primitives", "spheres", "triangles", "size", "median frame ms", "rays/s"]
    rows = [
        [escape(DEVICE_NAMES.get(r["device"], r["device"])), escape(r["options"]["scene"]), f"{primitives(r):,}",
         f"{r['spheres']:,}", f"{r['options']['triangles']:,}" if "triangles" in r["options"] else "–",
         f"{r['width']}x{r['height']}", fmt_ms(r["frame_ms"]["median"]),
         f"{fmt_num(r['rays_per_s'] / 1e6)} M" if r.get("rays_per_s") else "–"]
        for r in measured
    ]  # fmt: skip
    _findings(w, header, rows, verdicts(measured))
    _pictures(w, label, f"{slug}-scene", measured, lambda r: r["options"]["scene"].split()[0], primitives)


def _findings(w: _Writer, header: list[str], rows: list[list], verdict_lines: list[str]) -> None:
    """A part's table of frames, then its verdicts as a list."""
    w(_table(header, rows), "", *(f"- {line}" for line in verdict_lines), "")


def _pictures(w: _Writer, label: str, stem: str, records: list[dict], group, count) -> None:
    """Each group's frame at its largest count, as its record carries it (bench.pictures), a
    GPU's before the cpu's (the same picture within a step): a file beside report.md, shown in
    report.html. Records from before pictures were kept have none, and show none."""
    drawn = [r for r in records if r.get("picture")]
    names = sorted({group(r) for r in drawn})
    if not names:
        return
    w("As traced, each at its largest size measured:", "")
    for i, name in enumerate(names):
        r = max((r for r in drawn if group(r) == name), key=lambda r: (count(r), r["device"] != "cpu"))
        what = r["options"].get("scene") or f"{name}, {r['options']['atoms']:,} atoms"
        device = DEVICE_NAMES.get(r["device"], r["device"])
        w.picture(f"{stem}-{i + 1}.jpg", pictures.jpeg(r["picture"]), f"{label}: {what}, Whitted, on {device}")


def verdicts(measured: list[dict]) -> list[str]:
    """The suite's verdicts: each device's growth with the primitive count on each scene over
    its size factors, and each GPU's lead over the cpu on the scenes both measured."""
    out = []
    for device in sorted({r["device"] for r in measured}):
        growth = _growth([r for r in measured if r["device"] == device], lambda r: r["options"]["scene"].split()[0],
                         primitives)  # fmt: skip
        if growth:
            name = escape(DEVICE_NAMES.get(device, device))
            out.append(
                f"{name}: a frame's time grows as primitives^k over each scene's size factors: {'; '.join(growth)} "
                "(brute force's: ^1)"
            )
    cpu = {(r["options"]["scene"], r["width"], r["height"]): r["frame_ms"]["median"] for r in measured
           if r["device"] == "cpu"}  # fmt: skip
    for gpu in GPUS:
        leads = [cpu[key] / r["frame_ms"]["median"] for r in measured if r["device"] == gpu
                 for key in [(r["options"]["scene"], r["width"], r["height"])] if key in cpu]  # fmt: skip
        if leads:
            leads.sort()
            middle = statistics.median(leads)
            out.append(
                f"{escape(DEVICE_NAMES.get(gpu, gpu))} over the cpu on these scenes: median {fmt_x(middle)} "
                f"({fmt_x(leads[0])} to {fmt_x(leads[-1])}, {len(leads)} scenes), beside its lead on random "
                "spheres in the secondary rays' section"
            )
    return out


def _molecules(w: _Writer, label: str, slug: str, measured: list[dict]) -> None:
    """The molecule's frames at its copies, and their verdicts."""
    measured.sort(key=lambda r: (r["device"], r["options"]["molecule"], r["options"]["atoms"]))
    w(f"### {escape(label)}: molecules", "")
    w(
        "A molecule (the Protein Data Bank's entry named) drawn spacefill, one sphere an atom, with its own camera "
        f"and light, Whitted shading to {SCENES_DEPTH} bounces, through the BVH; alone, then copies of it side by "
        "side in a grid to reach millions of atoms: repeated for size, not chemistry.",
        "",
    )
    header = ["device", "molecule", "copies", "atoms", "size", "median frame ms", "rays/s"]
    rows = [
        [escape(DEVICE_NAMES.get(r["device"], r["device"])), escape(r["options"]["molecule"]),
         f"{r['options'].get('copies', 1):,}", f"{r['options']['atoms']:,}", f"{r['width']}x{r['height']}",
         fmt_ms(r["frame_ms"]["median"]), f"{fmt_num(r['rays_per_s'] / 1e6)} M" if r.get("rays_per_s") else "–"]
        for r in measured
    ]  # fmt: skip
    _findings(w, header, rows, molecule_verdicts(measured))
    _pictures(w, label, f"{slug}-molecule", measured, lambda r: r["options"]["molecule"],
              lambda r: r["options"]["atoms"])  # fmt: skip


def molecule_verdicts(measured: list[dict]) -> list[str]:
    """Each device's growth of a frame's time with the atom count over the copies, and each
    GPU's lead over the cpu on the points both measured."""
    out = []
    for device in sorted({r["device"] for r in measured}):
        growth = _growth([r for r in measured if r["device"] == device], lambda r: r["options"]["molecule"],
                         lambda r: r["options"]["atoms"], " atoms")  # fmt: skip
        if growth:
            out.append(
                f"{escape(DEVICE_NAMES.get(device, device))}: a molecule's frame grows as atoms^k over its copies: "
                f"{'; '.join(growth)} (brute force's: ^1; a tree's, which grows as log atoms: near 0)"
            )
    cpu = {_key(r): r["frame_ms"]["median"] for r in measured if r["device"] == "cpu"}
    for gpu in GPUS:
        leads = sorted((cpu[_key(r)] / r["frame_ms"]["median"], r["options"]["atoms"]) for r in measured
                       if r["device"] == gpu and _key(r) in cpu)  # fmt: skip
        if leads:
            ratio = [x for x, _ in leads]
            at_most = max(leads, key=lambda lead: lead[1])
            out.append(
                f"{escape(DEVICE_NAMES.get(gpu, gpu))} over the cpu on the molecules: median "
                f"{fmt_x(statistics.median(ratio))} ({fmt_x(ratio[0])} to {fmt_x(ratio[-1])}, {len(ratio)} points; "
                f"{fmt_x(at_most[0])} at {at_most[1]:,} atoms)"
            )
    return out


def _key(r: dict) -> tuple:
    return (r["options"]["molecule"], r["options"]["atoms"], r["width"], r["height"])
