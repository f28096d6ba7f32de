"""report.md's section of the meshes suite (bench/meshes.py): each mesh's frames by device,
triangle count and shading, and its two verdicts in the thesis's style, each a question with a
rule fixed before any data: how a frame's cost grows with the triangle count (a power law and a
logarithm fitted, with their R², by the thesis series' own fit), and what a GPU buys over the
CPU on triangles at the points both measured."""

from __future__ import annotations

import math
import statistics

from ..meshes import DEPTH, EYE, LIGHT, LIGHT_RADIUS, SHADOW_SAMPLES
from .beyond_sections import _rays_text
from .markdown_blocks import _table, _Writer, escape, write_verdict
from .numbers import fmt_ms, fmt_num, fmt_r2, fmt_x
from .series import DEVICE_NAMES, _fit, shading_of, way_of
from .verdicts import FAILS, HOLDS, NOT_MEASURED

GPUS = ("cuda", "wgpu")
# Fixed before any data: a BVH's walk visits about log(n) nodes, so a frame's time should grow
# far slower than the count; at most the cube root of it (a thousand times the triangles for
# at most ten times the time) is taken as "far slower". Brute force grows as n^1.
POWER_MAX = 1 / 3
GROWTH_QUESTION = "Through the BVH, does a frame's time grow far slower than the triangle count?"
GROWTH_RULE = (
    "Fixed before any data. Each series (a device and way of tracing, a mesh, a shading and a size) "
    "measured at two triangle counts or more gets two least-squares fits of its median frame times: "
    "a power law (log time against log triangles: time grows as triangles^k) and a logarithm (time "
    "against log triangles: so many ms more for each doubling of the triangles), each with its R² "
    "(shown from three counts on: two points fit any curve). The answer holds if every series' "
    f"exponent k is at most {fmt_num(POWER_MAX)} (a thousand times the triangles for at most ten times "
    "the time; brute force's k is 1), and does not hold if any is above it. Skipped points take "
    "no part."
)
LEAD_QUESTION = "Is the GPU faster than the CPU on triangles?"
LEAD_RULE = (
    "Fixed before any data. At every point both the CPU and the GPU (cuda) measured (the same mesh, "
    "triangle count, shading and size), the GPU's lead is the CPU's median frame time over the GPU's "
    "(whole frames: on a GPU, the copy back included), for each of the GPU's ways of tracing (its "
    "tree built on the host or on the GPU). The answer holds if every lead is above 1 and does not "
    "hold if any is not; it cannot be decided where no point was measured on both. wgpu's leads are "
    "shown for information and decide nothing."
)


def mesh_points(records: list[dict]) -> list[dict]:
    """One row per point of the meshes suite, measured or skipped: device, way of tracing, mesh,
    triangles, shading, size, and the median frame (and kernel) ms, rays a frame and a second,
    build s, or why it was skipped. Sorted by device, way, mesh, shading, size, triangles."""
    out = []
    for r in records:
        if r["suite"] != "meshes":
            continue
        opts = r.get("options") or {}
        out.append(
            {
                "device": r["device"],
                "way": way_of(r),
                "mesh": opts.get("mesh", "?"),
                "triangles": int(opts.get("triangles", 0)),
                "shading": shading_of(r),
                "width": r["width"],
                "height": r["height"],
                "skipped": r.get("skipped"),
                "median": None if "skipped" in r else float(r["frame_ms"]["median"]),
                "kernel": (r.get("kernel_ms") or {}).get("median"),
                "rays_per_frame": r.get("rays_per_frame") or (r["width"] * r["height"] if "skipped" not in r else None),
                "rays_per_s": r.get("rays_per_s"),
                "build_s": r.get("build_s"),
            }
        )
    return sorted(out, key=lambda p: (p["device"], p["way"], p["mesh"], p["shading"], p["width"] * p["height"],
                                      p["triangles"]))  # fmt: skip


def growth(records: list[dict]) -> list[dict]:
    """Each series with at least two triangle counts measured: its counts and median ms, the
    power fit (of log ms on log triangles: slope k) and the log fit (of ms on log triangles:
    slope in ms an e-fold), each series._fit's {slope, intercept, r2, n}."""
    groups: dict[tuple, list[dict]] = {}
    for p in mesh_points(records):
        if p["median"] is not None and p["triangles"] > 0:
            groups.setdefault((p["device"], p["way"], p["mesh"], p["shading"], p["width"], p["height"]), []).append(p)
    out = []
    for (device, way, mesh, shading, w, h), points in groups.items():
        counts = [p["triangles"] for p in points]
        if len(set(counts)) < 2:
            continue
        ms = [p["median"] for p in points]
        logs = [math.log(n) for n in counts]
        out.append(
            {"device": device, "way": way, "mesh": mesh, "shading": shading, "width": w, "height": h,
             "triangles": counts, "ms": ms, "power": _fit(logs, [math.log(m) for m in ms]), "log": _fit(logs, ms)}
        )  # fmt: skip
    return out


def _series_name(s: dict) -> str:
    return (
        f"{DEVICE_NAMES.get(s['device'], s['device'])} ({s['way']}), {s['mesh']}, {s['shading']}, "
        f"{s['width']}x{s['height']}"
    )


def _r2(fit: dict) -> str:
    return fmt_r2(fit["r2"]) if fit["n"] >= 3 else "– (two counts)"


def growth_verdict(records: list[dict]) -> dict:
    """GROWTH_QUESTION judged under GROWTH_RULE: verdict, measured (one line a series) and the series."""
    series = growth(records)
    if not series:
        return {"verdict": NOT_MEASURED, "measured": ["needs a series measured at two triangle counts or more"],
                "series": []}  # fmt: skip
    lines = []
    for s in series:
        k, per_doubling = s["power"]["slope"], s["log"]["slope"] * math.log(2)
        better = "the power law" if s["power"]["r2"] >= s["log"]["r2"] else "the logarithm"
        lines.append(
            f"{escape(_series_name(s))}: from {min(s['triangles']):,} to {max(s['triangles']):,} triangles "
            f"({len(s['triangles'])} counts) a frame grows as triangles^{k:.2f} (R² {_r2(s['power'])}), "
            f"or by {fmt_ms(per_doubling)} ms a doubling (R² {_r2(s['log'])})"
            + (f"; {better} fits better" if s["power"]["n"] >= 3 else "")
            + f": {HOLDS if k <= POWER_MAX else FAILS}"
        )
    verdict = HOLDS if all(s["power"]["slope"] <= POWER_MAX for s in series) else FAILS
    return {"verdict": verdict, "measured": lines, "series": series}


def leads(records: list[dict], gpu: str = "cuda") -> list[dict]:
    """The points both the CPU and `gpu` measured (mesh, triangles, shading, size), one entry for
    each of the GPU's ways: CPU and GPU median frame ms and the lead, the first over the second."""
    cpu: dict[tuple, float] = {}
    for p in mesh_points(records):
        if p["device"] == "cpu" and p["median"] is not None:
            cpu[(p["mesh"], p["triangles"], p["shading"], p["width"], p["height"])] = p["median"]
    out = []
    for p in mesh_points(records):
        key = (p["mesh"], p["triangles"], p["shading"], p["width"], p["height"])
        if p["device"] == gpu and p["median"] is not None and key in cpu:
            out.append({"way": p["way"], "mesh": p["mesh"], "triangles": p["triangles"], "shading": p["shading"],
                        "width": p["width"], "height": p["height"], "cpu_ms": cpu[key], "gpu_ms": p["median"],
                        "lead": cpu[key] / p["median"]})  # fmt: skip
    return out


def lead_verdict(records: list[dict], gpu: str = "cuda") -> dict:
    """LEAD_QUESTION judged under LEAD_RULE (for `gpu`: cuda decides, wgpu informs): verdict,
    measured (one line: each shading's leads) and the matched points."""
    matched = leads(records, gpu)
    name = "the GPU" if gpu == "cuda" else DEVICE_NAMES.get(gpu, gpu)
    if not matched:
        who = "the GPU (cuda)" if gpu == "cuda" else name
        why = f"cannot be decided: needs the meshes suite on both the CPU and {who} at the same points"
        return {"verdict": NOT_MEASURED, "measured": why, "points": []}
    parts = []
    for way in dict.fromkeys(p["way"] for p in matched):
        for shading in dict.fromkeys(p["shading"] for p in matched):
            mine = sorted(p["lead"] for p in matched if p["way"] == way and p["shading"] == shading)
            if mine:
                parts.append(
                    f"{way}, {shading} shading: {name} leads by a median {fmt_x(statistics.median(mine))} "
                    f"({fmt_x(mine[0])} to {fmt_x(mine[-1])}, {len(mine)} point{'s' * (len(mine) != 1)})"
                )
    slower = [p for p in matched if not p["lead"] > 1]
    text = "; ".join(parts) + (f"; not faster at {len(slower)} of {len(matched)}" if slower else "")
    return {"verdict": FAILS if slower else HOLDS, "measured": text, "points": matched}


def beside_embree(records: list[dict]) -> list[str]:
    """A line for each Embree figure among records (benchmarks/peers.py embreex: parts of quantity
    "embreex-intersect") taken on the suite's own rays (its icosphere, triangle count, size and
    eye distance) beside this suite's cpu frame there (thesis shading): rays/s each, and the
    ratio. Embree is information: no verdict reads it."""
    ours = {}
    for p in mesh_points(records):
        if p["device"] == "cpu" and p["mesh"] == "icosphere" and p["shading"] == "thesis" and p["rays_per_s"]:
            ours[(p["triangles"], p["width"], p["height"])] = p
    out = []
    for r in records:
        opts, values = r.get("options") or {}, r.get("values") or {}
        if r["suite"] != "parts" or r.get("quantity") != "embreex-intersect" or not values.get("rays_per_s"):
            continue
        mine = ours.get((opts.get("triangles"), r.get("width"), r.get("height")))
        if mine is None or opts.get("eye_distance") != abs(EYE[2]):
            continue
        threads = opts.get("threads")
        out.append(
            f"Embree 4 (embreex, closest hits only, {threads if isinstance(threads, int) else '?'} threads) on the "
            f"same rays, {mine['triangles']:,} triangles at {mine['width']}x{mine['height']}: "
            f"{_rays_text(values['rays_per_s'])} rays/s against raybench's cpu frame, "
            f"{_rays_text(mine['rays_per_s'])}: "
            f"raybench {fmt_x(mine['rays_per_s'] / values['rays_per_s'])} (for information)"
        )
    return out


def _section_meshes(w: _Writer, label: str, slug: str, records: list[dict]) -> None:
    """The meshes suite on one machine: a table of its points and its verdicts (no chart: slug is
    unused); records may hold the same run's parts too, for Embree's figures beside the cpu's."""
    points = mesh_points(records)
    if not points:
        return
    w(f"### {escape(label)}: triangles", "")
    w(
        "Two generated meshes (bench/meshes.py): `trimesh.creation.icosphere` of radius 1, 20 x 4^k triangles, "
        "and random triangles in the cube [-1, 1]^3 whose total area is the same at every count, both seen from "
        "(0, 0, -2) looking at the origin, a 60 degree field of view, every triangle matte. Each point is traced "
        "through the BVH with the thesis's shading (one primary ray a pixel) and with Whitted's to depth "
        f"{DEPTH} with {SHADOW_SAMPLES} shadow samples of one spherical light of radius {LIGHT_RADIUS} at {LIGHT} "
        "(on matte triangles: the primary rays and the shadow rays of the lit hits, every ray counted by the "
        "kernels). Rays/s are "
        "over the median whole frame. A point is skipped, and listed as such, where its frame is predicted "
        "(linear in pixels, and by the power of the triangle count its series has shown) to pass the suite's "
        "cap, or where the mesh would not fit in the host's or the device's memory.",
        "",
    )
    judged = growth_verdict(records)
    w(f"**{GROWTH_QUESTION}** **{judged['verdict']}**", "")
    w(*[f"- {line}" for line in judged["measured"]], "")
    w(f"The rule: {GROWTH_RULE}", "")
    lead = write_verdict(w, LEAD_QUESTION, lead_verdict, LEAD_RULE, records, points)
    embree = beside_embree(records)
    if embree:
        w(*[f"- {escape(line)}" for line in embree], "")
    if lead["points"]:
        w("The GPU's lead at each point both devices measured (CPU median frame ms / GPU's):", "")
        rows = [[escape(p["way"]), escape(p["mesh"]), f"{p['triangles']:,}", escape(p["shading"]),
                 f"{p['width']}x{p['height']}", fmt_ms(p["cpu_ms"]), fmt_ms(p["gpu_ms"]), fmt_x(p["lead"])]
                for p in lead["points"]]  # fmt: skip
        w(_table(["GPU's way", "mesh", "triangles", "shading", "size", "CPU ms", "GPU ms", "lead"], rows), "")
    header = ["device", "way", "mesh", "triangles", "shading", "size", "frame ms", "kernel ms", "rays a frame",
              "rays/s", "build ms"]  # fmt: skip
    rows = []
    for p in points:
        base = [escape(DEVICE_NAMES.get(p["device"], p["device"])), escape(p["way"]), escape(p["mesh"]),
                f"{p['triangles']:,}", escape(p["shading"]), f"{p['width']}x{p['height']}"]  # fmt: skip
        if p["median"] is None:
            rows.append(base + [f"skipped: {escape(p['skipped'])}"] + [""] * 4)
            continue
        rows.append(
            base
            + [fmt_ms(p["median"]), fmt_ms(p["kernel"]) if p["kernel"] else "–", f"{p['rays_per_frame']:,}",
               _rays_text(p["rays_per_s"]), fmt_ms(p["build_s"] * 1e3) if p["build_s"] is not None else "–"]
        )  # fmt: skip
    w(_table(header, rows), "")
