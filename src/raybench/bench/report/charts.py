"""The report's charts, as PNG bytes. Drawn on matplotlib Figure objects with
the Agg canvas attached explicitly: no pyplot, no display, no global backend
switch."""

from __future__ import annotations

import io
import math
import textwrap

from ...errors import controls_shown
from .numbers import fmt_ms, fmt_r2, fmt_x
from .series import DEVICE_NAMES
from .verdicts import THESIS_SPEEDUP


def _figure(ncols: int = 1, width: float = 7.5, height: float = 4.6):
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=(width, height), dpi=110, layout="constrained")
    FigureCanvasAgg(fig)
    axes = fig.subplots(1, ncols, squeeze=False)[0]
    for ax in axes:
        ax.grid(True, alpha=0.3)
    return fig, list(axes)


def _png(fig) -> bytes:
    from matplotlib.text import Text

    # a record's control characters (a label, a GPU's name) drawn as their escapes, as in report.md
    for text in fig.findobj(Text):
        text.set_text(controls_shown(text.get_text()))
    buf = io.BytesIO()
    fig.savefig(buf, format="png")
    return buf.getvalue()


def _name(ax, title: str, xlabel: str, ylabel: str | None = None) -> None:
    """A panel's title and the names of its axes; every panel's title is set in the one size."""
    ax.set_title(title, fontsize=10)
    ax.set_xlabel(xlabel)
    if ylabel is not None:
        ax.set_ylabel(ylabel)


def _linear_or_log(ax, values) -> None:
    values = [v for v in values if v and v > 0 and math.isfinite(v)]
    if values and max(values) / min(values) > 30:
        from matplotlib.ticker import ScalarFormatter

        ax.set_yscale("log")
        ax.yaxis.set_major_formatter(ScalarFormatter())
    else:
        ax.set_ylim(bottom=0)


def plot_thesis(label: str, device: str, series: list[dict], device_name: str) -> bytes:
    from matplotlib.lines import Line2D
    from matplotlib.patches import Patch

    fig, (ax,) = _figure()
    any_kernel = False
    for i, s in enumerate(series):
        color = f"C{i}"
        ax.fill_between(s["spheres"], s["p5"], s["p95"], color=color, alpha=0.2, linewidth=0)
        ax.plot(s["spheres"], s["median"], "o-", color=color, markersize=4, label=s["label"])
        if s["fit"]:
            xs = [min(s["spheres"]), max(s["spheres"])]
            ax.plot(xs, [s["fit"]["slope"] * x + s["fit"]["intercept"] for x in xs], "--", color=color, linewidth=1)
        if s["kernel"]:
            any_kernel = True
            ax.plot(s["spheres"], s["kernel"], ":", color=color, linewidth=1.5)
    handles, labels = ax.get_legend_handles_labels()
    handles += [Line2D([], [], color="gray", linestyle="--"), Patch(color="gray", alpha=0.2)]
    labels += ["least-squares line", "p5-p95 of frames"]
    if any_kernel:
        handles.append(Line2D([], [], color="gray", linestyle=":", linewidth=1.5))
        labels.append("kernel only (CUDA events)")
    ax.legend(handles, labels, fontsize=8)
    tests = [s["test"] for s in series if s["test"]]
    what = f"tests {min(tests)}-{max(tests)}" if tests else "thesis tests"
    # device_name is a results file's text: a "$" in it would start matplotlib's mathematics
    plain = str(device_name).replace("$", r"\$")
    title = f"{label}: {DEVICE_NAMES.get(device, device)} {what}, {plain}"
    _name(ax, title, "spheres in the scene", "median frame time (ms)")
    ax.set_ylim(bottom=0)
    ax.set_xlim(left=0)
    return _png(fig)


def plot_speedup(label: str, sp: list[dict], ratio: float | None) -> bytes:
    fig, (ax,) = _figure()
    sizes = sorted({(p["width"], p["height"]) for p in sp}, key=lambda s: s[0] * s[1])
    for i, (w, h) in enumerate(sizes):
        pts = [p for p in sp if (p["width"], p["height"]) == (w, h)]
        ax.plot(
            [p["spheres"] for p in pts],
            [p["speedup"] for p in pts],
            "o-",
            color=f"C{i}",
            markersize=4,
            label=f"{w}x{h}",
        )
    ax.axhspan(*THESIS_SPEEDUP, color="gray", alpha=0.35, label="thesis: 58-60x")
    if ratio:
        ax.axhline(ratio, color="C3", linestyle="--", label=f"theoretical FP32 ratio: {fmt_x(ratio)}")
    ax.axhline(1, color="black", linewidth=0.8, label="1x (no gain)")
    _linear_or_log(ax, [p["speedup"] for p in sp] + list(THESIS_SPEEDUP) + ([ratio] if ratio else []) + [1])
    title = f"{label}: GPU speedup over the CPU (CPU frame time / GPU frame time)"
    _name(ax, title, "spheres in the scene", "speedup (x)")
    ax.set_xlim(left=0)
    ax.legend(fontsize=8)
    return _png(fig)


def plot_test7(label: str, series: list[dict]) -> bytes:
    fig, axes = _figure(len(series), width=4.2 * len(series) + 1, height=4.2)
    for i, (ax, s) in enumerate(zip(axes, series)):
        ax.plot(
            s["spheres"], s["frame_ms"], "-", color=f"C{i}", linewidth=1, marker=".", markersize=3, label="frame time"
        )
        if s["kernel_ms"]:
            ax.plot(s["spheres"], s["kernel_ms"], "-", color="gray", linewidth=0.8, label="kernel only")
        if s["fit"]:
            xs = [min(s["spheres"]), max(s["spheres"])]
            ax.plot(
                xs,
                [s["fit"]["slope"] * x + s["fit"]["intercept"] for x in xs],
                "--",
                color="black",
                linewidth=1,
                label=f"least squares (R² {fmt_r2(s['fit']['r2'])})",
            )
        panel = f"{DEVICE_NAMES.get(s['device'], s['device'])}, {s['width']}x{s['height']}"
        _name(ax, panel, "spheres in the scene (10 more each frame)", "frame time (ms)")
        ax.set_ylim(bottom=0)
        ax.legend(fontsize=8)
    # wrapped to the figure: one series' figure is narrower than the title
    title = f"{label}: test 7, one frame per sphere count (first frame left out)"
    fig.suptitle(textwrap.fill(title, int(fig.get_figwidth() * 11)), fontsize=10)
    return _png(fig)


def _bars(ax, labels, groups, names, ylabel, best=True):
    """Grouped bars: groups is a list (one per bar series) of values per label."""
    n = len(groups)
    width = 0.8 / n
    for j, (values, name) in enumerate(zip(groups, names)):
        xs = [i + (j - (n - 1) / 2) * width for i in range(len(labels))]
        bars = ax.bar(xs, values, width, label=name, color=f"C{j}")
        ax.bar_label(bars, [fmt_ms(v) for v in values], fontsize=7, padding=1)
        if best and j == n - 1 and values:
            k = min(range(len(values)), key=values.__getitem__)
            bars[k].set_edgecolor("black")
            bars[k].set_linewidth(1.5)
    ax.set_xticks(range(len(labels)), labels, fontsize=8)
    ax.set_ylabel(ylabel)
    ax.margins(y=0.12)
    if n > 1 or names[0]:
        ax.legend(fontsize=8)


def plot_tuning(label: str, cpu: list[dict], gpu: list[dict]) -> bytes:
    panels = [p for p in (("cpu", cpu), ("cuda", gpu)) if p[1]]
    fig, axes = _figure(len(panels), width=6.5 * len(panels), height=4.4)
    for ax, (device, rows) in zip(axes, panels):
        r0 = rows[0]
        where = f"{r0['width']}x{r0['height']}, {r0['spheres']} spheres"
        if device == "cpu":
            _bars(
                ax,
                [f"{r['label']}\n{r['threads']} thread{'s' if r['threads'] != 1 else ''}" for r in rows],
                [[r["ms"] for r in rows]],
                [""],
                "median frame time (ms)",
            )
            ax.set_title(f"CPU threads ({where})", fontsize=10)
        else:
            has_kernel = all(r["kernel_ms"] is not None for r in rows)
            groups = [[r["frame_ms"] for r in rows]] + ([[r["kernel_ms"] for r in rows]] if has_kernel else [])
            names = ["whole frame", "kernel only"] if has_kernel else ["whole frame"]
            _bars(ax, [r["label"] for r in rows], groups, names, "median time (ms)")
            ax.set_xlabel("threads per block (x by y)")
            ax.tick_params(axis="x", labelrotation=45)
            ax.set_title(f"GPU block shapes ({where})", fontsize=10)
    fig.suptitle(f"{label}: tuning (the fastest bar is outlined)", fontsize=10)
    return _png(fig)


def plot_constant(label: str, rows_by_device: dict[str, list[dict]]) -> bytes:
    panels = [(d, rows) for d, rows in rows_by_device.items() if rows]
    fig, axes = _figure(len(panels), width=5.2 * len(panels) + 0.5, height=4.2)
    for ax, (device, rows) in zip(axes, panels):
        sizes = {(r["width"], r["height"]) for r in rows}
        names = [f"{r['spheres']}" if len(sizes) == 1 else f"{r['spheres']}\n{r['width']}x{r['height']}" for r in rows]
        timing = "kernel" if all(r["timing"] == "kernel" for r in rows) else "frame"
        _bars(
            ax,
            names,
            [[r["constant"] for r in rows], [r["runtime"] for r in rows]],
            ["constant (compile time)", "runtime variable"],
            f"median {timing} time (ms)",
            best=False,
        )
        where = f", {rows[0]['width']}x{rows[0]['height']}" if len(sizes) == 1 else ""
        _name(ax, f"{DEVICE_NAMES.get(device, device)}{where}", "spheres in the scene")  # _bars named y
    fig.suptitle(f"{label}: sphere count as a compile-time constant or a runtime variable", fontsize=10)
    return _png(fig)


def plot_scaling(label: str, series: list[dict]) -> bytes:
    fig, (ax,) = _figure(width=8.0, height=5.2)
    for i, s in enumerate(series):
        done = [p for p in s["points"] if p["median"] is not None]
        if not done:
            continue
        style = "o-" if s["accel"] == "bvh" else "s--"
        name = f"{DEVICE_NAMES.get(s['device'], s['device'])}, {s['way']}, {s['width']}x{s['height']}"
        ax.plot(
            [p["spheres"] for p in done], [p["median"] for p in done], style, color=f"C{i}", markersize=4, label=name
        )
        if all(p["kernel"] for p in done):
            ax.plot([p["spheres"] for p in done], [p["kernel"] for p in done], ":", color=f"C{i}", linewidth=1.2)
        cut = [p for p in s["points"] if p["median"] is None]
        if cut:
            ax.axvline(cut[0]["spheres"], color=f"C{i}", linewidth=0.6, alpha=0.5)
    ax.set_xscale("log")
    ax.set_yscale("log")
    title = f"{label}: frame time against sphere count (thin line: brute force stopped)"
    _name(ax, title, "spheres in the scene", "median frame time (ms); dotted: kernel only")
    ax.legend(fontsize=7)
    return _png(fig)


_SIZE_MARKERS = ("o", "s", "^", "D", "v", "P")
_DEVICE_COLORS = {"cpu": "C0", "cuda": "C1", "wgpu": "C2"}


def _secondary_panels(points: list[dict], value, ylabel: str, title: str, styles) -> bytes:
    """One panel per way of tracing (BVH, brute force): a line per device and
    size of `value(figures)` against the sphere count, for each (key, style)
    of styles (which record of the point: "whitted" or "primary")."""
    from matplotlib.lines import Line2D

    ways = list(dict.fromkeys(p["way"] for p in points))
    sizes = sorted({(p["width"], p["height"]) for p in points}, key=lambda s: s[0] * s[1])
    devices = list(dict.fromkeys(p["device"] for p in points))
    fig, axes = _figure(len(ways), width=5.6 * len(ways) + 2.2, height=4.8)
    for ax, way in zip(axes, ways):
        for device in devices:
            color = _DEVICE_COLORS.get(device, "C3")
            for size, marker in zip(sizes, _SIZE_MARKERS):
                mine = [p for p in points if (p["way"], p["device"], (p["width"], p["height"])) == (way, device, size)]
                for key, style in styles:
                    done = [(p["spheres"], value(p[key])) for p in mine if p[key] and value(p[key])]
                    if done:
                        xs, ys = zip(*done)
                        ax.plot(xs, ys, style, color=color, marker=marker, markersize=4, linewidth=1.2)
        ax.set_xscale("log")
        ax.set_yscale("log")
        _name(ax, way, "spheres in the scene", ylabel)
    handles = [Line2D([], [], color=_DEVICE_COLORS.get(d, "C3"), linewidth=3) for d in devices]
    labels = [DEVICE_NAMES.get(d, d) for d in devices]
    handles += [Line2D([], [], color="gray", linestyle="none", marker=m) for m in _SIZE_MARKERS[: len(sizes)]]
    labels += [f"{w}x{h}" for w, h in sizes]
    handles += [Line2D([], [], color="gray", linestyle=style) for _, style in styles]
    labels += [_STYLE_LABELS[key] for key, _ in styles]
    fig.legend(handles, labels, loc="outside right upper", fontsize=7)
    fig.suptitle(title, fontsize=10)
    return _png(fig)


_STYLE_LABELS = {"whitted": "Whitted frames, every ray counted", "primary": "thesis shading, primary rays only"}


def plot_secondary_rays(label: str, points: list[dict]) -> bytes:
    """Rays per second (median frames) against the sphere count: Whitted
    frames (solid) and their thesis-shading twins (dashed), by device and size."""
    return _secondary_panels(
        points,
        lambda f: f["rays_per_s"] if f["median"] is not None else None,
        "rays per second (median frame)",
        f"{label}: rays/s, Whitted frames (solid) and primary rays alone (dashed)",
        [("whitted", "-"), ("primary", "--")],
    )


def plot_secondary_frames(label: str, points: list[dict]) -> bytes:
    """Median Whitted frame time against the sphere count, by device and size."""
    settings = sorted(
        {(p["whitted"]["depth"], p["whitted"]["shadow_samples"]) for p in points if p["whitted"]}, key=str
    )
    shown = ", ".join(f"depth {d}, {n} shadow samples" for d, n in settings)
    return _secondary_panels(
        points,
        lambda f: f["median"],
        "median frame time (ms)",
        f"{label}: Whitted frame time ({shown})",
        [("whitted", "-")],
    )


def plot_multi_gpu(label: str, series: list[dict]) -> bytes:
    """Throughput against workers, one panel per job, a line per device and
    size, and dashed the linear scaling of its one-worker point."""
    jobs = list(dict.fromkeys(s["job"] for s in series))
    fig, axes = _figure(len(jobs), width=5.2 * len(jobs) + 0.6, height=4.4)
    for ax, job in zip(axes, jobs):
        for i, s in enumerate(x for x in series if x["job"] == job):
            color = _DEVICE_COLORS.get(s["device"], f"C{i + 3}")
            xs = [p["workers"] for p in s["points"]]
            what = f"{DEVICE_NAMES.get(s['device'], s['device'])} {s['width']}x{s['height']}"
            ax.plot(xs, [p["frames_per_s"] for p in s["points"]], "o-", color=color, label=what)
            if s["one"]:
                ax.plot(xs, [s["one"] * n for n in xs], "--", color=color, linewidth=1, label=f"{what}, linear")
        title = "one frame in tiles" if job == "frame" else "a sequence of frames"
        _name(ax, title, "workers (one device each)", "frames per second")
        ax.set_ylim(bottom=0)
        ax.set_xticks(sorted({p["workers"] for s in series for p in s["points"]}))
        ax.legend(fontsize=7)
    fig.suptitle(f"{label}: throughput against workers, linear dashed", fontsize=10)
    return _png(fig)
