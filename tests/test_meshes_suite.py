"""The meshes suite (raybench.bench.meshes): its points, its meshes, the cap's prediction from a
series' growth, the points that do not fit, a quick run on the cpu end to end (records under the
schema, rays as a render casts them) and its report section's verdicts, each figure worked out
again from the records."""

import json
import math
import re
import statistics

import jsonschema
import numpy as np
import pytest

import raybench
from raybench import RaybenchError
from raybench.bench import meshes, results, runner, stats, suites
from raybench.bench.report.meshes_section import POWER_MAX, growth_verdict, lead_verdict
from raybench.bench.results import ResultsWriter
from raybench.cli import run

RUN = {"label": "x", "machine": {}}


def test_the_quick_points_are_small_meshes_both_shadings_through_the_bvh():
    points = suites.points(["meshes"], ["cpu"], quick=True, cores=2, accels=("none",))
    assert len(points) == 12 and {p.suite for p in points} == {"meshes"}
    assert [(p.options["mesh"], p.options["triangles"], p.options["shading"]) for p in points[:4]] == [
        ("icosphere", 320, "thesis"),
        ("icosphere", 320, "whitted"),
        ("icosphere", 1280, "thesis"),
        ("icosphere", 1280, "whitted"),
    ]
    for p in points:
        # the BVH whatever --accel asked for (brute force over millions of triangles is no question)
        assert p.device == "cpu" and (p.width, p.height) == meshes.QUICK_SIZE and p.spheres == 0
        assert p.options["accel"] == "bvh" and p.options["cap_s"] == meshes.QUICK_CAP_S
        if p.options["shading"] == "whitted":
            assert (p.options["depth"], p.options["shadow_samples"]) == (5, 4)
        assert f"{p.options['triangles']:,} triangles" in p.describe()


def test_the_full_points_reach_ten_million_triangles_on_every_device():
    points = suites.points(["meshes"], ["cpu", "cuda", "wgpu"], cores=2, builds=("host", "gpu"))
    on = {d: [p for p in points if p.device == d] for d in ("cpu", "cuda", "wgpu")}
    counts = sorted({(p.options["mesh"], p.options["triangles"]) for p in on["cpu"]})
    assert counts == sorted([("icosphere", 20 * 4**k) for k in range(5, 10)] + [("random", 10**k) for k in range(4, 8)])
    assert all((p.width, p.height) == (1680, 1050) and p.options["cap_s"] == meshes.CAP_S for p in points)
    # the GPUs once for each build asked for, the cpu once
    assert len(on["cuda"]) == len(on["wgpu"]) == 2 * len(on["cpu"]) == 2 * 2 * len(counts)
    assert {p.options["build"] for p in on["cuda"]} == {"host", "gpu"} and "build" not in on["cpu"][0].options


def test_the_meshes_are_what_the_docstring_says():
    sphere = meshes.icosphere(1280)
    assert len(sphere) == 1280
    assert np.allclose(np.linalg.norm(sphere.vertices.astype(np.float64), axis=1), 1.0, atol=1e-6)
    with pytest.raises(ValueError):
        meshes.icosphere(1000)

    def area(mesh) -> float:
        a, b, c = (mesh.vertices[mesh.faces[:, i]].astype(np.float64) for i in range(3))
        return float(0.5 * np.linalg.norm(np.cross(b - a, c - a), axis=1).sum())

    small, large = meshes.random_triangles(1000, 7), meshes.random_triangles(100_000, 7)
    assert np.array_equal(small.vertices, meshes.random_triangles(1000, 7).vertices)  # seeded
    assert not np.array_equal(small.vertices, meshes.random_triangles(1000, 8).vertices)
    # the same total area at every count, every corner near the cube [-1, 1]^3
    assert area(large) == pytest.approx(area(small), rel=0.05)
    side = meshes.RANDOM_EDGE * math.sqrt(meshes.RANDOM_REFERENCE / 1000)
    assert np.abs(small.vertices).max() <= 1 + side / 2 and len(small.vertices) == 3 * len(small)


def test_a_frame_is_predicted_by_the_growth_its_series_has_shown():
    assert meshes.predicted_ms(100, 10, []) is None
    # one point: linear in pixels and triangles
    assert meshes.predicted_ms(200, 40, [(100, 10, 5.0)]) == pytest.approx(5.0 * 2 * 4)
    # two: the power they showed (here 0.5), exact for a power law
    assert meshes.predicted_ms(100, 1000, [(100, 10, 1.0), (100, 100, 10**0.5)]) == pytest.approx(10.0)
    # a shrinking time predicts no growth; a superlinear one no more than linear
    assert meshes.predicted_ms(100, 1000, [(100, 10, 2.0), (100, 100, 1.0)]) == pytest.approx(1.0)
    assert meshes.predicted_ms(100, 1000, [(100, 10, 1.0), (100, 100, 1000.0)]) == pytest.approx(10_000.0)


def test_the_cap_skips_what_the_series_growth_puts_past_it(tmp_path, monkeypatch, rng):
    """Frames that grow as triangles^0.6 (and linearly in pixels): every point measured whose time
    is within the cap, every later one skipped, each with the time the power law gives it."""
    scale = rng.uniform(7.5, 9.0)  # s at 1M triangles, 1680x1050: 5.2M and 10M pass the 20 s cap, 1.3M does not

    def exact_ms(p):
        return scale * 1e3 * (p.options["triangles"] / 1e6) ** 0.6 * p.width * p.height / (1680 * 1050)

    measured = []

    def fake_measure(point, scenes, duration):
        measured.append(point)
        return {**runner._identity(point), "frame_ms": stats.summarize([exact_ms(point)])}

    monkeypatch.setattr(runner, "measure", fake_measure)
    points = suites.points(["meshes"], ["cpu"], cores=2)
    with ResultsWriter(tmp_path / "r.jsonl") as w:
        runner.run(points, w, RUN, 0.1, 0, progress=False)
    records = results.read(tmp_path / "r.jsonl")
    assert len(records) == len(points)
    cap_ms = meshes.CAP_S * 1e3
    assert measured == [p for p in points if exact_ms(p) <= cap_ms]
    skipped = [(r, p) for r, p in zip(records, points) if "skipped" in r]
    assert {p.options["triangles"] for _, p in skipped} == {5_242_880, 10_000_000}
    for r, p in skipped:
        assert r["predicted_ms"] == pytest.approx(exact_ms(p)) and "cap" in r["skipped"]


def test_a_mesh_that_does_not_fit_is_skipped_with_the_reason(monkeypatch):
    point = suites.Point("meshes", "cpu", 32, 20, 0, {"accel": "bvh", "mesh": "random", "triangles": 320,
                                                     "shading": "thesis", "cap_s": 2.0})  # fmt: skip
    monkeypatch.setattr(meshes, "HOST_TRIANGLE_BYTES", 2**50)
    record = runner.measure(point, runner.Scenes(0), 0.05)
    assert record["skipped"].startswith("does not fit: needs about ") and "GiB on the host" in record["skipped"]
    results.check_record({**record, "run": RUN}, "record")
    monkeypatch.undo()

    def refused(*args, **kwargs):
        raise RaybenchError("bvh: 320 triangles need 9 GiB for the BVH and the frame, more than the 1 GiB available")

    monkeypatch.setattr(runner, "Renderer", refused)
    record = runner.measure(point, runner.Scenes(0), 0.05)
    assert record["skipped"].startswith("does not fit: bvh: 320 triangles need 9 GiB for the BVH")
    assert record["predicted_ms"] is None
    results.check_record({**record, "run": RUN}, "record")
    # a sphere point's refusal is no skip: the run stops with its line, as before
    with pytest.raises(RaybenchError):
        runner.measure(suites.Point("scaling", "cpu", 32, 20, 10, {"accel": "bvh"}), runner.Scenes(0), 0.05)


@pytest.mark.slow
def test_a_quick_run_on_the_cpu_and_its_report(tmp_path, capsys):
    code = run(["bench", "--quick", "--suite", "meshes", "--device", "cpu", "--duration", "0.05",
                "--out", str(tmp_path), "--label", "ci"])  # fmt: skip
    out = capsys.readouterr().out
    assert code == 0, out
    (path,) = tmp_path.glob("results-*.jsonl")
    validator = jsonschema.Draft202012Validator(results.schema())
    for line in path.read_text().splitlines():
        assert not list(validator.iter_errors(json.loads(line)))
    records = results.read(path)
    planned = suites.points(["meshes"], ["cpu"], quick=True)
    assert [(r["options"]["mesh"], r["options"]["triangles"], r["options"]["shading"]) for r in records] == [
        (p.options["mesh"], p.options["triangles"], p.options["shading"]) for p in planned
    ]
    w, h = meshes.QUICK_SIZE
    for r in records:
        assert "skipped" not in r and r["spheres"] == 0 and r["frames"] >= 3
        if r["options"]["shading"] == "thesis":
            assert r["rays_per_s"] == pytest.approx(w * h / (r["frame_ms"]["median"] / 1e3))
        else:  # every ray counted: one primary a pixel, and at most 4 shadow rays a hit (none bounce off matte)
            assert r["rays"]["primary"] == w * h and 0 < r["rays"]["shadow"] <= 4 * w * h
            assert r["rays"]["reflection"] == r["rays"]["refraction"] == 0
            assert r["rays_per_frame"] == sum(r["rays"].values())
    # the rays the runner's frames cast are those of a frame of the same mesh, camera and light
    whitted = next(r for r in records if r["options"]["shading"] == "whitted" and r["options"]["mesh"] == "random")
    scene = meshes.mesh_scene("random", whitted["options"]["triangles"], 0)
    frame = raybench.render(scene, width=w, height=h, device="cpu", shading="whitted", depth=5, shadow_samples=4)
    assert whitted["rays"] == frame.rays
    # the report's growth, series by series, worked out again from the records with NumPy
    text = next(tmp_path.glob("report-*/report.md")).read_text()
    assert "### ci: triangles" in text and "Is the GPU faster than the CPU on triangles?** **not measured**" in text
    powers = []
    for mesh in ("icosphere", "random"):
        for shading in ("thesis", "whitted"):
            mine = [r for r in records if (r["options"]["mesh"], r["options"]["shading"]) == (mesh, shading)]
            n = np.log([r["options"]["triangles"] for r in mine])
            ms = np.array([r["frame_ms"]["median"] for r in mine])
            k = np.polyfit(n, np.log(ms), 1)[0]
            powers.append(k)
            line = re.search(rf"- CPU \(BVH\), {mesh}, {shading}, {w}x{h}: .*", text).group(0)
            assert f"grows as triangles^{k:.2f} (R² " in line, (line, k)
            assert line.endswith(": holds" if k <= POWER_MAX else ": does not hold")
    verdict = "holds" if max(powers) <= POWER_MAX else "does not hold"
    assert f"triangle count?** **{verdict}**" in text
    # Embree's figure on the suite's own rays (peers.py embreex's record, the same label) beside the cpu's
    ours = next(r for r in records if (r["options"]["mesh"], r["options"]["shading"]) == ("icosphere", "thesis"))
    n, theirs_ms = ours["options"]["triangles"], 2.5 * ours["frame_ms"]["median"]
    part = {"format": "raybench-results", "version": 1, "suite": "parts", "quantity": "embreex-intersect",
            "device": "cpu", "width": w, "height": h, "samples": 3, "time_ms": stats.summarize([theirs_ms]),
            "options": {"primitive": "triangle", "triangles": n, "eye_distance": 2.0, "threads": 2},
            "values": {"rays_per_s": w * h / (theirs_ms / 1e3)}, "run": ours["run"]}  # fmt: skip
    far = {**part, "options": {**part["options"], "eye_distance": 3.0}}  # other rays: not set beside
    (tmp_path / "embreex.jsonl").write_text("".join(json.dumps(r) + "\n" for r in (part, far)))
    assert run(["report", str(tmp_path), "-o", str(tmp_path / "both")]) == 0
    text = (tmp_path / "both" / "report.md").read_text()
    (line,) = [line for line in text.splitlines() if line.startswith("- Embree 4 (embreex")]
    assert f"{n:,} triangles at {w}x{h}" in line and line.endswith(": raybench 2.50x (for information)"), line


def _record(device, mesh, triangles, shading, ms, **options):
    return {"suite": "meshes", "device": device, "width": 320, "height": 200, "spheres": 0,
            "options": {"accel": "bvh", "mesh": mesh, "triangles": triangles, "shading": shading, **options},
            "frame_ms": {"median": ms}}  # fmt: skip


def test_the_verdicts_from_synthetic_records(rng):
    counts = [20_480, 81_920, 327_680]
    k = rng.uniform(0.05, 0.3)
    cpu = [_record("cpu", "icosphere", n, s, 10.0 * (n / 1e4) ** k) for n in counts for s in ("thesis", "whitted")]
    judged = growth_verdict(cpu)
    assert judged["verdict"] == "holds" and len(judged["series"]) == 2
    assert all(s["power"]["slope"] == pytest.approx(k) and s["power"]["r2"] == pytest.approx(1.0)
               for s in judged["series"])  # fmt: skip
    # one series past the rule's power: the answer does not hold
    steep = [_record("cpu", "random", n, "thesis", (n / 1e4) ** 0.9) for n in counts]
    assert growth_verdict(cpu + steep)["verdict"] == "does not hold"
    # the GPU's lead: the CPU's median over the GPU's at each point both measured, every way
    factors = rng.uniform(2.0, 50.0, len(cpu))
    gpu = [{**r, "device": "cuda", "frame_ms": {"median": r["frame_ms"]["median"] / f}} for r, f in zip(cpu, factors)]
    lead = lead_verdict(cpu + gpu)
    assert lead["verdict"] == "holds" and len(lead["points"]) == len(cpu)
    assert sorted(p["lead"] for p in lead["points"]) == pytest.approx(sorted(factors))
    thesis = [f for r, f in zip(cpu, factors) if r["options"]["shading"] == "thesis"]
    said = re.search(r"thesis shading: the GPU leads by a median ([\d.]+)x", lead["measured"]).group(1)
    assert float(said) == pytest.approx(statistics.median(thesis), rel=1e-2)  # (three digits shown)
    slow = [{**gpu[0], "frame_ms": {"median": cpu[0]["frame_ms"]["median"] * 2}}] + gpu[1:]
    assert lead_verdict(cpu + slow)["verdict"] == "does not hold"
    assert lead_verdict(cpu)["verdict"] == "not measured" and growth_verdict(cpu[:2])["verdict"] == "not measured"
