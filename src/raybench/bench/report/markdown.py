"""The report as Markdown: report.md beside its PNG charts.

Text taken from a results file (labels, CPU and GPU names, settings, notes)
enters the Markdown only through escape(): a results file is data, and must
not put HTML, links or images into the report."""

from __future__ import annotations

import json
import re
from pathlib import Path

from ... import references as raybench_references
from ...errors import RaybenchError
from ...files import folder_atomic, write_atomic
from ...kernels.whitted import KINDS
from .. import headline
from ..suites import REGISTRY
from . import charts, html
from .data import (
    DEVICE_NAMES,
    constant_vs_runtime,
    cpu_tuning,
    dynamic_points,
    fmt_opt,
    gpu_tuning,
    largest_group,
    load,
    machine_of,
    multi_gpu_series,
    parts_rows,
    scaling_series,
    secondary_points,
    speedups,
    test7_series,
    theoretical_ratio,
    thesis_series,
)
from .numbers import fmt_ms, fmt_num, fmt_r2, fmt_x
from .verdicts import (
    CLAIMS,
    RULES,
    SECONDARY_QUESTION,
    SECONDARY_RULE,
    THESIS_CPU,
    THESIS_GPU,
    THESIS_RATIO,
    secondary_verdict,
    verdicts,
    with_reference_gpus,
)

# Character references, not backslashes: a reference is never Markdown syntax,
# whatever stands before it, and _cell's escaping of "|" cannot undo it.
_INERT = str.maketrans(
    {
        "&": "&amp;",
        "<": "&lt;",  # HTML tags and autolinks
        ">": "&gt;",
        "[": "&#91;",  # links and images
        "]": "&#93;",
        "\\": "&#92;",  # backslash escapes
        "`": "&#96;",  # code spans
        "*": "&#42;",  # emphasis
        "|": "&#124;",  # table cells
        "\n": " ",
        "\r": " ",
    }
)


def escape(text) -> str:
    """Text from a results file (a label, a CPU model, a setting, a note) as
    inert Markdown: it shows as written and adds no HTML, link, image, code,
    emphasis or table cell. Every such text enters the report through here."""
    return str(text).translate(_INERT)


def _cell(text) -> str:
    """A table cell of the report's own text (record text is escape()d first)."""
    return str(text).replace("|", "\\|").replace("\n", " ")


def _table(header: list[str], rows: list[list]) -> str:
    lines = ["| " + " | ".join(_cell(h) for h in header) + " |", "|" + "---|" * len(header)]
    lines += ["| " + " | ".join(_cell(c) for c in row) + " |" for row in rows]
    return "\n".join(lines)


def _slug(label: str, taken: set) -> str:
    slug = re.sub(r"[^A-Za-z0-9._-]+", "-", label).strip("-.") or "machine"
    base, i = slug, 2
    while slug in taken:
        slug, i = f"{base}-{i}", i + 1
    taken.add(slug)
    return slug


def _adapter_name(records: list[dict]) -> str:
    """The wgpu adapter of these records, e.g. "llvmpipe (...) (Vulkan, CPU)": a CPU driver must not pass for a GPU."""
    names = sorted(
        {
            f"{a.get('name')} ({a.get('backend')}, {a.get('type')})"
            for r in records
            if r["device"] == "wgpu" and isinstance(a := r.get("adapter"), dict)
        }
    )
    return ", ".join(names) or "unknown adapter"


def _gpu_name(machine: dict) -> str:
    gpus = machine.get("gpus") or []
    return gpus[0].get("name", "unknown GPU") if gpus else "no CUDA GPU"


def _machine_lines(label: str, records: list[dict]) -> list[str]:
    # every value below is the results file's text: escaped where it is read
    m = machine_of(records)
    cpu = {k: escape(v) for k, v in (m.get("cpu") or {}).items()}
    versions = {k: escape(v) if v else v for k, v in (m.get("versions") or {}).items()}
    gpus = [{k: escape(v) if v else v for k, v in g.items()} for g in m.get("gpus") or []]
    gpu = (
        (
            f"{gpus[0].get('name')} ({gpus[0].get('multiprocessors', '?')} multiprocessors, "
            f"{gpus[0].get('memory_gib', '?')} GiB, driver {gpus[0].get('driver') or '?'})"
        )
        if gpus
        else "no CUDA GPU"
    )
    lines = [
        f"**{escape(label)}**: CPU {cpu.get('model', '?')} ({cpu.get('physical_cores', '?')} cores, "
        f"{cpu.get('logical_cpus', '?')} threads); GPU {gpu}; {escape(m.get('os', ''))}; "
        f"raybench {versions.get('raybench') or '?'}, numba {versions.get('numba') or '?'}, "
        f"numba-cuda {versions.get('numba-cuda') or '?'}."
    ]
    runs = {}
    for r in records:
        runs.setdefault(r["run"].get("id"), (r["run"], []))[1].append(r)
    for run, rs in runs.values():
        settings = run.get("settings") or {}
        shown = escape(", ".join(f"{k} {fmt_opt(v)}" for k, v in settings.items()))
        lines.append(
            f"- run {escape(run.get('id', '?'))}: {escape(run.get('date', '?'))}, "
            f"git {escape(run.get('git_commit') or 'unknown')}, {len(rs)} points; settings: {shown or 'none recorded'}"
        )
    machines = {json.dumps(r["run"]["machine"].get("cpu"), sort_keys=True) for r in records}
    if len(machines) > 1:
        lines.append(
            "- note: the runs under this label describe different CPUs; the first run's machine is used "
            "for the theoretical rates"
        )
    return lines


def _rates_text(machine: dict) -> str:
    ratio = theoretical_ratio(machine)
    # the machine's own text, escaped where it is read; fp32_gflops stays a number for fmt_num
    cpu = {k: v if k == "fp32_gflops" else escape(v) for k, v in (machine.get("cpu") or {}).items()}
    gpus = [{k: v if k == "fp32_gflops" else escape(v) for k, v in g.items()} for g in machine.get("gpus") or []]
    parts = []
    if cpu.get("fp32_gflops"):
        parts.append(
            f"CPU {fmt_num(cpu['fp32_gflops'])} GFLOP/s FP32 ({cpu.get('physical_cores', '?')} cores x "
            f"{cpu.get('clock_ghz', '?')} GHz x {cpu.get('fp32_lanes', '?')} {cpu.get('simd', '')} lanes x 2 "
            f"(multiply-add) x {cpu.get('fma_units_per_core', '?')} FMA units)"
        )
    else:
        parts.append("CPU FP32 rate unknown")
    if gpus and gpus[0].get("fp32_gflops"):
        g = gpus[0]
        parts.append(
            f"GPU {fmt_num(g['fp32_gflops'])} GFLOP/s FP32 ({g.get('multiprocessors', '?')} multiprocessors x "
            f"{g.get('fp32_lanes_per_sm', '?')} lanes x 2 x {g.get('clock_ghz', '?')} GHz)"
        )
    else:
        parts.append("GPU FP32 rate unknown")
    text = "; ".join(parts) + (f": a theoretical ratio of **{fmt_x(ratio)}**." if ratio else ".")
    return (
        text + f" (The thesis counted cores x GHz and no SIMD: {THESIS_GPU} against {THESIS_CPU} gives "
        f"{fmt_num(THESIS_RATIO)}x. Counting the CPU's SIMD lanes, as these rates do, gives a far smaller ratio "
        "for the same two chips.)"
    )


class _Writer:
    """Collects the report's lines and writes each plot as soon as it is drawn."""

    def __init__(self, out_dir: Path):
        self.out_dir = out_dir
        self.lines: list[str] = []
        self.pngs: list[Path] = []

    def __call__(self, *lines: str) -> None:
        self.lines.extend(lines)

    def image(self, name: str, data: bytes, alt: str) -> None:
        path = self.out_dir / name
        write_atomic(path, data)
        self.pngs.append(path)
        self(f"![{escape(alt)}]({name})", "")  # alt names the machine: the results file's text


def _section_thesis(w: _Writer, label: str, slug: str, records: list[dict]) -> None:
    w("### Tests 1-6: frame time against sphere count", "")
    series = thesis_series(records)
    if not series:
        w("Not measured: these results hold no `thesis` suite (`raybench bench --suite thesis`).", "")
        return
    w(
        "Each chart shows one processor: the median time to render one frame (dots, solid line) for 100 to "
        "1000 spheres at each resolution, the spread of the frames from the 5th to the 95th percentile "
        "(shaded band, often thinner than the line), and the least-squares straight line (dashed). If the "
        "dots sit on the dashed line, frame time grows linearly with the number of spheres, as the thesis "
        "says. The slope is the cost of one more sphere for the whole picture; the intercept is the cost of "
        "a frame with no spheres (launch, copy, overhead). R² is 1 for a perfect line.",
        "",
    )
    machine = machine_of(records)
    for device in ("cuda", "wgpu", "cpu"):
        ds = [s for s in series if s["device"] == device]
        if not ds:
            if device != "wgpu":  # the portable backend is news where measured, not a gap where not
                w(f"{DEVICE_NAMES[device]}: not measured.", "")
            continue
        name = (
            _gpu_name(machine)
            if device == "cuda"
            else _adapter_name(records)
            if device == "wgpu"
            else (machine.get("cpu") or {}).get("model", "CPU")
        )
        w(f"**{DEVICE_NAMES[device]}** ({escape(name)})", "")
        w.image(
            f"{slug}-thesis-{device}.png",
            charts.plot_thesis(label, device, ds, name),
            f"{label}: {DEVICE_NAMES[device]} frame time against spheres",
        )
        counts = sorted({n for s in ds for n in s["spheres"]})
        kernel = any(s["kernel"] for s in ds)
        header = ["resolution", "test", "slope (ms/sphere)", "intercept (ms)", "R²"] + [f"{n}" for n in counts]
        if kernel:
            header += ["kernel ms at max count", "kernel slope (ms/sphere)"]
        header += ["ray-sphere tests/s at max count"]
        rows = []
        for s in ds:
            f = s["fit"]
            at = dict(zip(s["spheres"], s["median"]))
            row = [
                f"{s['width']}x{s['height']}",
                escape(s["test"] or "–"),
                fmt_num(f["slope"]) if f else "–",
                fmt_num(f["intercept"]) if f else "–",
                fmt_r2(f["r2"]) if f else "–",
            ]
            row += [fmt_ms(at[n]) if n in at else "" for n in counts]
            if kernel:
                row += [
                    fmt_ms(s["kernel"][-1]) if s["kernel"] else "–",
                    fmt_num(s["kernel_fit"]["slope"]) if s["kernel_fit"] else "–",
                ]
            tps = s["tests_per_s"][-1]
            row.append(f"{fmt_num(tps / 1e9)} G" if tps else "–")
            rows.append(row)
        w("Median frame time (ms) at each sphere count, and the line fitted to it:", "", _table(header, rows), "")


def _section_speedup(w: _Writer, label: str, slug: str, records: list[dict]) -> None:
    w("### GPU over CPU speedup", "")
    sp = speedups(records)
    machine = machine_of(records)
    ratio = theoretical_ratio(machine)
    if not sp:
        w(
            "Not measured: this needs tests 1-6 on both the CPU and the GPU at the same resolutions and sphere counts.",
            "",
            f"Theoretical rates: {_rates_text(machine)}",
            "",
        )
        return
    w(
        "How many times faster the GPU renders the same frame than the CPU (CPU median frame time divided by "
        "GPU median frame time, whole frames including the GPU's copy back to the host). The grey band is the "
        "thesis's 58-60x; the red dashed line is what the two processors' peak FP32 rates would predict if both "
        "ran the ray tracer equally close to their peak.",
        "",
    )
    w(f"Theoretical rates: {_rates_text(machine)}", "")
    w.image(f"{slug}-speedup.png", charts.plot_speedup(label, sp, ratio), f"{label}: GPU speedup over CPU")
    counts = sorted({p["spheres"] for p in sp})
    sizes = sorted({(p["width"], p["height"]) for p in sp}, key=lambda s: s[0] * s[1])
    at = {(p["width"], p["height"], p["spheres"]): p["speedup"] for p in sp}
    rows = [[f"{wd}x{ht}"] + [fmt_x(at[(wd, ht, n)]) if (wd, ht, n) in at else "" for n in counts] for wd, ht in sizes]
    w(_table(["resolution"] + [f"{n}" for n in counts], rows), "")


def _section_test7(w: _Writer, label: str, slug: str, records: list[dict]) -> None:
    w("### Test 7: adding ten spheres every frame", "")
    series = test7_series(records)
    if not series:
        w("Not measured: these results hold no test 7 (it runs with `--suite thesis`).", "")
        return
    w(
        "As in the thesis, the scene starts with 10 spheres and gets 10 more every frame up to 1000; each dot "
        "is one frame, with the sphere count passed to the kernel at run time. The very first frame is left "
        "out of the chart and the fit, because it includes setting everything up (its time is given below). "
        "Single frames are noisier than the medians of tests 1-6.",
        "",
    )
    w.image(f"{slug}-test7.png", charts.plot_test7(label, series), f"{label}: test 7 frame time against spheres")
    rows = []
    for s in series:
        f = s["fit"]
        rows.append(
            [
                escape(DEVICE_NAMES.get(s["device"], s["device"])),
                f"{s['width']}x{s['height']}",
                len(s["spheres"]),
                fmt_num(f["slope"]) if f else "–",
                fmt_num(f["intercept"]) if f else "–",
                fmt_r2(f["r2"]) if f else "–",
                fmt_ms(s["first_frame_s"] * 1e3) if s["first_frame_s"] is not None else "–",
                fmt_num(s["compile_s"]) if s["compile_s"] is not None else "–",
            ]
        )
    w(
        _table(
            [
                "device",
                "resolution",
                "frames",
                "slope (ms/sphere)",
                "intercept (ms)",
                "R²",
                "first frame, left out (ms)",
                "compile (s)",
            ],
            rows,
        ),
        "",
    )


def _section_tuning(w: _Writer, label: str, slug: str, records: list[dict]) -> None:
    w("### Tuning: CPU threads and GPU block shapes", "")
    cpu, gpu, portable = cpu_tuning(records), gpu_tuning(records), gpu_tuning(records, "wgpu")
    if not cpu and not gpu and not portable:
        w("Not measured: these results hold no `tuning` suite (`raybench bench --suite tuning`).", "")
        return
    w(
        "The same frame rendered with different ways of splitting the work. On the CPU the rows of the picture "
        "are shared among a number of threads (the thesis found twice the cores best, and one thread per row "
        "worse than a single thread). On the GPU every pixel is one thread, and threads are grouped in blocks "
        "of the shape shown (the thesis found the largest, 32x32, best). Lower is faster; the fastest bar is "
        "outlined.",
        "",
    )
    for device, _rows in (("cpu", cpu), ("cuda", gpu)):
        _, others = largest_group(records, "tuning", device)
        if others:
            w(
                f"({DEVICE_NAMES[device]} tuning was also measured at {others} smaller size(s); the largest is shown.)",
                "",
            )
    if cpu or gpu:
        w.image(f"{slug}-tuning.png", charts.plot_tuning(label, cpu, gpu), f"{label}: tuning")
    if cpu:
        fastest = min(r["ms"] for r in cpu)
        w(
            _table(
                ["CPU setting", "threads", "median frame ms", "relative to fastest"],
                [[escape(r["label"]), escape(r["threads"]), fmt_ms(r["ms"]), fmt_x(r["ms"] / fastest)] for r in cpu],
            ),
            "",
        )
    else:
        w("CPU tuning: not measured.", "")
    if gpu:
        fastest = min(r["ms"] for r in gpu)
        timing = "kernel" if all(r["kernel_ms"] is not None for r in gpu) else "frame"
        w(
            _table(
                ["GPU block", "median frame ms", "median kernel ms", f"relative to fastest ({timing})"],
                [
                    [
                        escape(r["label"]),
                        fmt_ms(r["frame_ms"]),
                        fmt_ms(r["kernel_ms"]) if r["kernel_ms"] is not None else "–",
                        fmt_x(r["ms"] / fastest),
                    ]
                    for r in gpu
                ],
            ),
            "",
        )
    else:
        w("GPU tuning: not measured.", "")
    if portable:
        fastest = min(r["ms"] for r in portable)
        timing = "kernel" if all(r["kernel_ms"] is not None for r in portable) else "frame"
        w(
            f"wgpu workgroups, on {escape(_adapter_name(records))}:",
            "",
            _table(
                ["wgpu workgroup", "median frame ms", "median kernel ms", f"relative to fastest ({timing})"],
                [
                    [
                        escape(r["label"]),
                        fmt_ms(r["frame_ms"]),
                        fmt_ms(r["kernel_ms"]) if r["kernel_ms"] is not None else "–",
                        fmt_x(r["ms"] / fastest),
                    ]
                    for r in portable
                ],
            ),
            "",
        )


def _section_constant(w: _Writer, label: str, slug: str, records: list[dict]) -> None:
    w("### Sphere count: compile-time constant or runtime variable", "")
    rows = {d: constant_vs_runtime(records, d) for d in ("cuda", "cpu")}
    if not any(rows.values()):
        w(
            "Not measured: these results hold no `constant-vs-runtime` suite "
            "(`raybench bench --suite constant-vs-runtime`).",
            "",
        )
        return
    w(
        "The thesis's test 7 passed the sphere count to the shader at run time and blamed that for slower "
        "frames than a count fixed when the shader is compiled (which lets the compiler unroll the loop). "
        "Here the same kernel is compiled both ways and timed at each sphere count; a ratio above 1 means the "
        "runtime count is slower. On the GPU the kernel time is compared where it was measured.",
        "",
    )
    w.image(f"{slug}-constant.png", charts.plot_constant(label, rows), f"{label}: constant vs runtime sphere count")
    table = []
    for device, rs in rows.items():
        for r in rs:
            table.append(
                [
                    DEVICE_NAMES[device],
                    f"{r['width']}x{r['height']}",
                    r["spheres"],
                    r["timing"],
                    fmt_ms(r["constant"]),
                    fmt_ms(r["runtime"]),
                    fmt_num(r["ratio"]),
                ]
            )
    w(
        _table(
            ["device", "resolution", "spheres", "timing", "constant (ms)", "runtime (ms)", "runtime / constant"], table
        ),
        "",
    )
    for device, rs in rows.items():
        if not rs:
            w(f"{DEVICE_NAMES[device]}: not measured.", "")


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
    judged = secondary_verdict(records)
    w(f"**{SECONDARY_QUESTION}** **{judged['verdict']}**: {escape(judged['measured'])}", "")
    if any(p["device"] == "wgpu" for p in points):
        info = secondary_verdict(records, "wgpu")
        w(f"wgpu on {escape(_adapter_name(records))}, for information: {escape(info['measured'])}", "")
    w(f"The rule: {SECONDARY_RULE}", "")
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


def _section_dynamic(w: _Writer, label: str, records: list[dict]) -> None:
    """The dynamic suite on one machine: a table of frames a second."""
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


def _section_parts(w: _Writer, label: str, records: list[dict]) -> None:
    """The parts suite of one run: what a benchmark script timed that is no suite's frame (a build, a
    start-up, a launch, a part of a frame), a row each, as measured."""
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


def _claims_table(machines: dict[str, list[dict]]) -> tuple[str, dict[str, list[dict]]]:
    judged = {label: verdicts(records) for label, records in machines.items()}
    header = ["#", "the thesis's claim", "what the thesis measured"] + [escape(label) for label in machines]
    rows = []
    for i, (claim, thesis) in enumerate(CLAIMS):
        row = [i + 1, claim, thesis]
        for label in machines:
            v = judged[label][i]
            row.append(f"**{v['verdict']}**: {escape(v['measured'])}")  # names settings from the results
        rows.append(row)
    return _table(header, rows), judged


def _section_references(w: _Writer, machines: dict[str, list[dict]], references: list[dict]) -> None:
    """The headline beside the reference machines, and the claims that need a GPU judged,
    where a machine here has none, with each reference GPU: always named as another machine."""
    mine = [r for records in machines.values() for r in records]
    w("## Beside the reference machines", "")
    w(
        "raybench ships results measured on other machines (benchmarks/make_references.py makes them from the "
        "records under benchmarks/results/). They are **not** this run's machines: each is named, with the "
        "commit it was measured at. `raybench report --no-references` leaves this section out.",
        "",
    )
    table = headline.rows(mine, references)
    if table:
        w(f"The {escape(headline.DEFINITION)} (raybench.bench.headline):", "")
        rows = [
            [
                escape(r["label"]) + (" (reference: another machine)" if r["reference"] else ""),
                escape(r["name"]),
                fmt_num(r["value"]),
                fmt_x(r["cpu_ratio"]) if r["cpu_ratio"] else "–",
                escape(r["commit"] or "not recorded"),
            ]
            for r in table
        ]
        w(_table(["machine", "device", "million rays/s", "x this run's CPU", "commit"], rows), "")
    for pair in with_reference_gpus(machines, references):
        label, ref, gpu_name, judged = pair["label"], pair["ref"], pair["gpu"], pair["judged"]
        w(
            f"### {escape(label)}: the claims that need a GPU, with the {escape(gpu_name)} of {escape(ref)} "
            "(another machine)",
            "",
            f"This machine has no GPU in these results; below, its CPU is set against {escape(ref)}'s GPU, "
            f"measured elsewhere (commit {escape(pair['commit'])}, {escape(pair['date'])}). Claims 4 and 6 are "
            "that GPU's alone.",
            "",
        )
        rows = [[v["number"], v["claim"], f"**{v['verdict']}**: {escape(v['measured'])}"] for v in judged]
        w(_table(["#", "the thesis's claim", f"this CPU with {escape(ref)}'s GPU"], rows), "")


def write_report(paths: list, out_dir, references: bool = True) -> Path:
    """Read the results files, write out_dir/report.md and its PNG plots, and
    report.html beside them (out_dir is created if needed), and return the
    path of report.md.
    references: place the machines against raybench's reference machines
    (raybench.references), and judge the claims a missing GPU leaves open with theirs."""
    out_dir = Path(out_dir)
    if out_dir.exists() and not out_dir.is_dir():
        raise RaybenchError(f"{out_dir}: is a file, not a folder for the report")
    sources: list = []
    machines, notes = load(paths, sources)
    # the suites with a section of their own (suites.Suite.section) are no part of the thesis's claims, nor are parts
    beyond: dict[str, dict[str, list[dict]]] = {r: {} for s in REGISTRY if s.section for r in s.writes}
    beyond["parts"] = {}
    for records in machines.values():
        for r in records:
            if r["suite"] in beyond:
                beyond[r["suite"]].setdefault(r["run"]["label"], []).append(r)
    machines = {k: v for k, v in ((k, [r for r in v if r["suite"] not in beyond]) for k, v in machines.items()) if v}
    # built aside and renamed into place: never a half-made report under out_dir's name
    with folder_atomic(out_dir, _ours) as staged:
        _write(sources, machines, notes, beyond, _Writer(staged), raybench_references.load() if references else None)
    return out_dir / "report.md"


def _ours(entry: Path) -> bool:
    """What an earlier report left in its folder, which a new one may replace."""
    return (
        entry.is_file()
        and not entry.is_symlink()
        and (entry.name in ("report.md", "report.html") or entry.suffix == ".png")
    )


def _write(sources, machines, notes, beyond, w: _Writer, references: list[dict] | None) -> None:
    scaling, secondary = beyond["scaling"], beyond["secondary"]
    multi_gpu, dynamic, parts = beyond["multi-gpu"], beyond["dynamic"], beyond["parts"]
    names = ", ".join(
        dict.fromkeys(
            [records[0]["run"]["label"] for records in machines.values() if records]
            + list(scaling)
            + list(secondary)
            + list(multi_gpu)
            + list(dynamic)
            + list(parts)
        )
    )
    w(f"# raybench: the 2010 GPU ray-tracing thesis, measured again on {escape(names)}", "")
    w(
        "Persson and Udd (2010) rendered spheres with one brute-force ray tracer (one primary ray per pixel, "
        f"tested against every sphere) on an {THESIS_CPU} and on a {THESIS_GPU} with a DirectX 11 compute "
        "shader. raybench runs the same algorithm, written once, on this machine's CPU (Numba) and GPU "
        "(numba-cuda), repeats the thesis's tests, and checks each of its claims below. Times are medians "
        "over many frames; every number comes from the results files listed at the end.",
        "",
    )
    w("## Machines", "")
    for label, records in machines.items():
        w(*_machine_lines(label, records), "")
    w("## The thesis's claims", "")
    table, judged = _claims_table(machines)
    w(table, "", "How the verdicts are decided:", "")
    w(*[f"- {rule}" for rule in RULES], "")
    if references:
        _section_references(w, machines, references)
    taken: set = set()
    for label, records in machines.items():
        slug = _slug(label, taken)
        w(f"## {escape(label)}", "")
        w(*_machine_lines(label, records), "")
        for section in (_section_thesis, _section_speedup, _section_test7, _section_tuning, _section_constant):
            section(w, label, slug, records)
    if scaling:
        w("## Beyond the thesis: scaling with a BVH", "")
        for label, records in scaling.items():
            _section_scaling(w, label, _slug(f"{label}-scaling", taken), records)
    if secondary:
        w("## Beyond the thesis: secondary rays", "")
        for label, records in secondary.items():
            described = any(rs[0]["run"]["label"] == label for rs in machines.values())
            _section_secondary(w, label, _slug(f"{label}-secondary", taken), records, describe=not described)
    if multi_gpu:
        w("## Beyond the thesis: across GPUs and workers", "")
        for label, records in multi_gpu.items():
            _section_multi_gpu(w, label, _slug(f"{label}-multi-gpu", taken), records)
    if dynamic:
        w("## Beyond the thesis: spheres that move", "")
        for label, records in dynamic.items():
            _section_dynamic(w, label, records)
    if parts:
        w("## Beyond the thesis: parts timed apart", "")
        for label, records in parts.items():
            _section_parts(w, label, records)
    w("## Sources", "")
    # a file's name is the user's text like any other: escaped, never a code span it could end
    w(*[f"- {escape(p)}" for p in sources], "")
    if notes:
        w("## Notes", "")
        w(*[f"- {escape(n)}" for n in notes], "")
    write_atomic(w.out_dir / "report.md", "\n".join(w.lines).encode("utf-8"))
    write_atomic(w.out_dir / "report.html", html.render(sources, machines, notes, references).encode("utf-8"))
