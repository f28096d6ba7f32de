"""report.md's sections of one machine's thesis tests: the thesis's
series, the GPU's speed-up over the CPU, test 7, the tuning of threads and
blocks, and the sphere count as a constant or a variable."""

from __future__ import annotations

from . import charts
from .markdown_blocks import _adapter_name, _table, _Writer, escape
from .numbers import fmt_compile_s, fmt_ms, fmt_num, fmt_r2, fmt_slope, fmt_x
from .series import (
    DEVICE_NAMES,
    constant_vs_runtime,
    cpu_tuning,
    gpu_tuning,
    largest_group,
    machine_of,
    speedups,
    test7_series,
    theoretical_ratio,
    thesis_series,
)
from .verdicts import THESIS_CPU, THESIS_GPU, THESIS_RATIO


def _gpu_name(machine: dict) -> str:
    gpus = machine.get("gpus") or []
    return gpus[0].get("name", "unknown GPU") if gpus else "no CUDA GPU"


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


def _opening(w: _Writer, title: str, measured, missing: str, intro: str) -> bool:
    """A section's heading, then what it shows (intro) or, where nothing was
    measured, the line that says so (missing) in place of the section:
    whether anything was."""
    w(f"### {title}", "", intro if measured else missing, "")
    return bool(measured)


def _no_suite(suite: str) -> str:
    """What a section says where the results hold none of its suite's records."""
    return f"Not measured: these results hold no `{suite}` suite (`raybench bench --suite {suite}`)."


def _fit_cells(fit: dict | None, spheres: list[int]) -> list[str]:
    """Slope, intercept and R² of a fitted line, as table cells: tests 1-6 and test 7 show the same fit."""
    if not fit:
        return ["–", "–", "–"]
    return [fmt_slope(fit["slope"], spheres), fmt_num(fit["intercept"]), fmt_r2(fit["r2"])]


def _section_thesis(w: _Writer, label: str, slug: str, records: list[dict]) -> None:
    series = thesis_series(records)
    if not _opening(
        w,
        "Tests 1-6: frame time against sphere count",
        series,
        _no_suite("thesis"),
        "Each chart shows one processor: the median time to render one frame (dots, solid line) for 100 to "
        "1000 spheres at each resolution, the spread of the frames from the 5th to the 95th percentile "
        "(shaded band, often thinner than the line), and the least-squares straight line (dashed). If the "
        "dots sit on the dashed line, frame time grows linearly with the number of spheres, as the thesis "
        "says. The slope is the cost of one more sphere for the whole picture; the intercept is the cost of "
        "a frame with no spheres (launch, copy, overhead). R² is 1 for a perfect line.",
    ):
        return
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
            at = dict(zip(s["spheres"], s["median"]))
            row = [
                f"{s['width']}x{s['height']}",
                escape(s["test"] or "–"),
                *_fit_cells(s["fit"], s["spheres"]),
            ]
            row += [fmt_ms(at[n]) if n in at else "–" for n in counts]
            if kernel:
                row += [
                    fmt_ms(s["kernel"][-1]) if s["kernel"] else "–",
                    fmt_slope(s["kernel_fit"]["slope"], s["spheres"]) if s["kernel_fit"] else "–",
                ]
            tps = s["tests_per_s"][-1]
            row.append(f"{fmt_num(tps / 1e9)} G" if tps else "–")
            rows.append(row)
        w("Median frame time (ms) at each sphere count, and the line fitted to it:", "", _table(header, rows), "")


def _section_speedup(w: _Writer, label: str, slug: str, records: list[dict]) -> None:
    sp = speedups(records)
    machine = machine_of(records)
    ratio = theoretical_ratio(machine)
    measured = _opening(
        w,
        "GPU over CPU speedup",
        sp,
        "Not measured: this needs tests 1-6 on both the CPU and the GPU at the same resolutions and sphere counts.",
        "How many times faster the GPU renders the same frame than the CPU (CPU median frame time divided by "
        "GPU median frame time, whole frames including the GPU's copy back to the host). The grey band is the "
        "thesis's 58-60x; the red dashed line is what the two processors' peak FP32 rates would predict if both "
        "ran the ray tracer equally close to their peak.",
    )
    w(f"Theoretical rates: {_rates_text(machine)}", "")
    if not measured:
        return
    w.image(f"{slug}-speedup.png", charts.plot_speedup(label, sp, ratio), f"{label}: GPU speedup over CPU")
    counts = sorted({p["spheres"] for p in sp})
    sizes = sorted({(p["width"], p["height"]) for p in sp}, key=lambda s: s[0] * s[1])
    at = {(p["width"], p["height"], p["spheres"]): p["speedup"] for p in sp}
    rows = [[f"{wd}x{ht}"] + [fmt_x(at[(wd, ht, n)]) if (wd, ht, n) in at else "" for n in counts] for wd, ht in sizes]
    w(_table(["resolution"] + [f"{n}" for n in counts], rows), "")


def _section_test7(w: _Writer, label: str, slug: str, records: list[dict]) -> None:
    series = test7_series(records)
    missing = "Not measured: these results hold no test 7 (it runs with `--suite thesis`)."
    if not _opening(
        w,
        "Test 7: adding ten spheres every frame",
        series,
        missing,
        "As in the thesis, the scene starts with 10 spheres and gets 10 more every frame up to 1000; each dot "
        "is one frame, with the sphere count passed to the kernel at run time. The very first frame is left "
        "out of the chart and the fit, because it includes setting everything up (its time is given below). "
        "Single frames are noisier than the medians of tests 1-6.",
    ):
        return
    w.image(f"{slug}-test7.png", charts.plot_test7(label, series), f"{label}: test 7 frame time against spheres")
    rows = [
        [
            escape(DEVICE_NAMES.get(s["device"], s["device"])),
            f"{s['width']}x{s['height']}",
            len(s["spheres"]),
            *_fit_cells(s["fit"], s["spheres"]),
            fmt_ms(s["first_frame_s"] * 1e3) if s["first_frame_s"] is not None else "–",
            fmt_compile_s(s["compile_s"]),
        ]
        for s in series
    ]
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
    cpu, gpu, portable = cpu_tuning(records), gpu_tuning(records), gpu_tuning(records, "wgpu")
    if not _opening(
        w,
        "Tuning: CPU threads and GPU block shapes",
        cpu or gpu or portable,
        _no_suite("tuning"),
        "The same frame rendered with different ways of splitting the work. On the CPU the rows of the picture "
        "are shared among a number of threads (the thesis found twice the cores best, and one thread per row "
        "worse than a single thread). On the GPU every pixel is one thread, and threads are grouped in blocks "
        "of the shape shown (the thesis found the largest, 32x32, best). Lower is faster; the fastest bar is "
        "outlined.",
    ):
        return
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
        w(_gpu_tuning_table("GPU block", gpu), "")
    else:
        w("GPU tuning: not measured.", "")
    if portable:
        w(
            f"wgpu workgroups, on {escape(_adapter_name(records))}:",
            "",
            _gpu_tuning_table("wgpu workgroup", portable),
            "",
        )


def _gpu_tuning_table(first: str, rows: list[dict]) -> str:
    """One table for CUDA blocks and wgpu workgroups: both are a launch shape timed by frame and, where the
    device reports it, by kernel; the ratio uses the kernel time only when every row has one."""
    fastest = min(r["ms"] for r in rows)
    timing = "kernel" if all(r["kernel_ms"] is not None for r in rows) else "frame"
    return _table(
        [first, "median frame ms", "median kernel ms", f"relative to fastest ({timing})"],
        [
            [
                escape(r["label"]),
                fmt_ms(r["frame_ms"]),
                fmt_ms(r["kernel_ms"]) if r["kernel_ms"] is not None else "–",
                fmt_x(r["ms"] / fastest),
            ]
            for r in rows
        ],
    )


def _section_constant(w: _Writer, label: str, slug: str, records: list[dict]) -> None:
    rows = {d: constant_vs_runtime(records, d) for d in ("cuda", "cpu")}
    title = "Sphere count: compile-time constant or runtime variable"
    if not _opening(
        w,
        title,
        any(rows.values()),
        _no_suite("constant-vs-runtime"),
        "The thesis's test 7 passed the sphere count to the shader at run time and blamed that for slower "
        "frames than a count fixed when the shader is compiled (which lets the compiler unroll the loop). "
        "Here the same kernel is compiled both ways and timed at each sphere count; a ratio above 1 means the "
        "runtime count is slower. On the GPU the kernel time is compared where it was measured.",
    ):
        return
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
