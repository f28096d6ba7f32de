"""report.md's sections beyond the thesis, one a suite: scaling with a
BVH, across GPUs and workers, secondary rays, spheres that move, and parts
timed apart."""

from __future__ import annotations

from ...layout import KINDS
from . import charts
from .markdown_blocks import _machine_lines, _table, _Writer, escape, write_verdict
from .numbers import fmt_ms, fmt_num, fmt_x
from .records import fmt_opt
from .series import DEVICE_NAMES, dynamic_points, multi_gpu_series, parts_rows, scaling_series, secondary_points
from .verdicts import SECONDARY_QUESTION, SECONDARY_RULE, secondary_verdict


def _section_scaling(w: _Writer, label: str, slug: str, records: list[dict]) -> None:
    series = scaling_series(records)
    if not series:
        return
    w(f"### {escape(label)}: scaling from 10 to 1,000,000 spheres", "")
    w(
        "Median frame time against the number of spheres (`random_spheres`, default camera), on log-log axes: "
        "brute force grows linearly (slope 1), the BVH about logarithmically. Brute force stops where its next "
        "frame, predicted linear in spheres from the last one measured, would pass the cap; those points are "
        "listed as skipped, not left out. BVH build time is measured apart from the frames.",
        "",
    )
    w.image(f"{slug}.png", charts.plot_scaling(label, series), f"{label}: frame time against sphere count")
    header = ["device", "way", "size", "spheres", "median frame ms", "kernel ms", "rays/s", "build ms"]
    rows = []
    for s in series:
        for p in s["points"]:
            base = [
                escape(DEVICE_NAMES.get(s["device"], s["device"])),
                escape(s["way"]),
                f"{s['width']}x{s['height']}",
                f"{p['spheres']:,}",
            ]
            if p["median"] is None:
                rows.append(base + [f"skipped: {escape(p['skipped'])}", "", "", ""])
                continue
            rows.append(
                base
                + [
                    fmt_ms(p["median"]),
                    fmt_ms(p["kernel"]) if p["kernel"] else "–",
                    f"{fmt_num(p['rays_per_s'] / 1e6)} M" if p["rays_per_s"] else "–",
                    fmt_ms(p["build_s"] * 1e3) if p["build_s"] is not None else "–",
                ]
            )
    w(_table(header, rows), "")


def _section_multi_gpu(w: _Writer, label: str, slug: str, records: list[dict]) -> None:
    series = multi_gpu_series(records)
    if not series:
        return
    w(f"### {escape(label)}: across workers", "")
    w(
        "Throughput of 1..N workers of raybench.cluster (each a process owning one device: a GPU, or on the "
        "CPU one thread), each after one untimed run that warmed every worker. One frame in tiles is traced "
        "and assembled in one place; a sequence's frames are traced where they run and only counted here. "
        "Efficiency is the throughput over N times one worker's (1 is linear).",
        "",
    )
    w.image(f"{slug}.png", charts.plot_multi_gpu(label, series), f"{label}: throughput against workers")
    header = ["device", "job", "size", "spheres", "workers", "frames/s", "speedup", "efficiency"]
    rows = []
    for s in series:
        job = "one frame in tiles" if s["job"] == "frame" else f"{s['frames']} frames"
        if s.get("delivery"):
            job += f" ({s['delivery']})"
        for p in s["points"]:
            rows.append(
                [
                    escape(DEVICE_NAMES.get(s["device"], s["device"])),
                    escape(job),
                    f"{s['width']}x{s['height']}",
                    f"{s['spheres']:,}",
                    p["workers"],
                    fmt_num(p["frames_per_s"]),
                    fmt_x(p["speedup"]) if p["speedup"] else "–",
                    f"{p['efficiency']:.0%}" if p["efficiency"] else "–",
                ]
            )
    w(_table(header, rows), "")


def _rays_text(x) -> str:
    """Rays per second in M, or G from a billion on (the issue's targets are in G rays/s)."""
    if not x:
        return "–"
    return f"{fmt_num(x / 1e9)} G" if x >= 1e9 else f"{fmt_num(x / 1e6)} M"


def _section_secondary(w: _Writer, label: str, slug: str, records: list[dict], describe: bool = False) -> None:
    """The secondary suite on one machine; describe: the machine too, where no other section does."""
    points = secondary_points(records)
    if not points:
        return
    w(f"### {escape(label)}: secondary rays", "")
    if describe:
        w(*_machine_lines(label, records), "")
    w(
        "Whitted frames of the materials scene (`random_spheres(n, seed, materials=True)`: plastic, mirrors "
        "and glass, one area light), each beside the same spheres at the same size and way of tracing with "
        "the thesis's shading (one primary ray a pixel), measured in the same run. Rays per second count "
        "every ray a frame cast, of every kind, as the kernels counted them (not estimates), over the median "
        "frame time (whole frames: on a GPU, the copy back included; where the device has its own clock, over "
        "the kernel time as well). Brute force is Whitted's simple loop over every sphere, for its twin too. "
        "A brute-force point is skipped, and listed as such, where its frame is predicted (linear in pixels "
        "and spheres from the last one measured) to pass the suite's cap: with secondary rays at 100,000 "
        "spheres a CPU would take tens of minutes a frame on 16 cores and hours on 2, so a CPU's brute force "
        "stops there or before, while a GPU's runs on. The BVH runs every point.",
        "",
    )
    judged = write_verdict(w, SECONDARY_QUESTION, secondary_verdict, SECONDARY_RULE, records, points)
    w.image(f"{slug}-rays.png", charts.plot_secondary_rays(label, points), f"{label}: rays per second")
    w.image(f"{slug}-frames.png", charts.plot_secondary_frames(label, points), f"{label}: Whitted frame time")
    header = ["device", "way", "size", "spheres", "frame ms", "kernel ms", "rays a frame: primary"]
    header += ["shadow", "reflection", "refraction", "rays/s", "rays/s (kernel)", "primary rays/s (thesis shading)"]
    rows = []
    for p in points:
        wh, pr = p["whitted"], p["primary"]
        base = [
            escape(DEVICE_NAMES.get(p["device"], p["device"])),
            escape(p["way"]),
            f"{p['width']}x{p['height']}",
            f"{p['spheres']:,}",
        ]
        primary = (
            f"skipped: {escape(pr['skipped'])}" if pr and pr["skipped"] else _rays_text(pr["rays_per_s"]) if pr else "–"
        )
        if wh is None or wh["skipped"]:
            why = f"skipped: {escape(wh['skipped'])}" if wh else "not measured"
            rows.append(base + [why] + [""] * 8 + [primary])
            continue
        rays = wh["rays"] or {}
        rows.append(
            base
            + [fmt_ms(wh["median"]), fmt_ms(wh["kernel"]) if wh["kernel"] else "–"]
            + [f"{rays[k]:,}" if isinstance(rays.get(k), int) else "–" for k in KINDS]
            + [_rays_text(wh["rays_per_s"]), _rays_text(wh["kernel_rays_per_s"]), primary]
        )
    w(_table(header, rows), "")
    if judged["points"]:
        w("The GPU's lead at each point both devices measured (GPU rays/s / CPU rays/s, median frames):", "")
        w(
            _table(
                ["way", "size", "spheres", "CPU rays/s", "GPU rays/s", "lead, secondary", "lead, primary", "kept"],
                [
                    [
                        escape(p["way"]),
                        f"{p['width']}x{p['height']}",
                        f"{p['spheres']:,}",
                        _rays_text(p["cpu_rays_per_s"]),
                        _rays_text(p["gpu_rays_per_s"]),
                        fmt_x(p["secondary"]),
                        fmt_x(p["primary"]),
                        fmt_num(p["kept"]),
                    ]
                    for p in judged["points"]
                ],
            ),
            "",
        )


def _section_dynamic(w: _Writer, label: str, slug: str, records: list[dict]) -> None:
    """The dynamic suite on one machine: a table of frames a second (no chart: slug is unused)."""
    points = dynamic_points(records)
    if not points:
        return
    w(f"### {escape(label)}: spheres that move every frame", "")
    w(
        "Every frame moves the spheres (`raybench.animate.Orbits`: each on a circle of 1.5 of its radii through "
        "its start, seeded like the scene), updates the BVH and traces the frame; frames/s is from the median "
        "frame (update and trace, the copy to the host included). The tree is rebuilt on the host (cpu, wgpu, "
        "and cuda with build host, then uploaded) or, with build gpu, refitted on the GPU while its SAH cost "
        "stays within the refit limit of a fresh tree's, else rebuilt there. Update share: the updates' time "
        "over the frames'. The positions themselves are computed before each frame's clock starts.",
        "",
    )
    header = ["device", "build", "size", "spheres", "frames/s", "frame ms", "update ms", "kernel ms", "update share",
              "refits / builds"]  # fmt: skip
    rows = [
        [
            escape(DEVICE_NAMES.get(p["device"], p["device"])),
            escape(p["build"]),
            f"{p['width']}x{p['height']}",
            f"{p['spheres']:,}",
            fmt_num(p["frames_per_s"]),
            fmt_ms(p["frame_ms"]),
            fmt_ms(p["update_ms"]),
            fmt_ms(p["kernel_ms"]) if p["kernel_ms"] else "–",
            f"{p['update_share']:.0%}" if p["update_share"] is not None else "–",
            f"{p['updates'].get('refit', 0)} / {p['updates'].get('build', 0)}",
        ]
        for p in points
    ]
    w(_table(header, rows), "")


def _section_parts(w: _Writer, label: str, slug: str, records: list[dict]) -> None:
    """The parts suite of one run: what a benchmark script timed that is no suite's frame (a build, a
    start-up, a launch, a part of a frame), a row each, as measured (no chart: slug is unused)."""
    rows = parts_rows(records)
    w(f"### {escape(label)}: parts timed apart", "")
    header = ["quantity", "device", "spheres", "size", "options", "median ms", "p5-p95 ms", "samples", "figures"]
    w(
        _table(
            header,
            [
                [
                    escape(p["quantity"]),
                    escape(DEVICE_NAMES.get(p["device"], p["device"])),
                    f"{p['spheres']:,}" if p["spheres"] is not None else "–",
                    p["size"] or "–",
                    escape(", ".join(f"{k} {fmt_opt(v)}" for k, v in p["options"].items())) or "–",
                    fmt_ms(p["time_ms"]["median"]),
                    f"{fmt_ms(p['time_ms']['p5'])}-{fmt_ms(p['time_ms']['p95'])}",
                    p["samples"] if p["samples"] is not None else "–",
                    escape(
                        ", ".join(
                            f"{k} {v:,}" if isinstance(v, int) else f"{k} {fmt_num(v)}" for k, v in p["values"].items()
                        )
                    )
                    or "–",
                ]
                for p in rows
            ],
        ),
        "",
    )
