"""The scenes suite (raybench.bench.scenes): its points, a point measured through the runner
with the scene's own view, and its report section's verdicts."""

import io

import numpy as np
import pytest
from PIL import Image

import raybench
from raybench import RaybenchError
from raybench.bench import pictures, results, runner, suites
from raybench.bench import scenes as real
from raybench.bench.report.scenes_section import _section_scenes, molecule_verdicts, slope, verdicts

RUN = {"label": "x", "machine": {}}


def test_the_quick_points_are_small_scenes_with_their_counts():
    points = suites.points(["scenes"], ["cpu"], quick=True, cores=2, accels=("bvh",))
    assert [(p.options.get("scene", p.options.get("molecule")), p.spheres) for p in points] == [
        ("balls 1", 10), ("balls 2", 91), ("balls 3", 820), ("tetra 3", 0), ("gears 1", 0),
        ("1tii", 5_469)]  # fmt: skip
    for p in points:
        assert p.suite == "scenes" and p.device == "cpu" and (p.width, p.height) == real.QUICK_SCENES_SIZE
        assert p.options["shading"] == "whitted" and p.options["depth"] == real.SCENES_DEPTH
    by_name = {p.options["scene"]: p.options for p in points if "scene" in p.options}
    # the molecule alone, its copies and atoms named
    assert {k: points[-1].options[k] for k in ("molecule", "copies", "atoms", "style")} == {
        "molecule": "1tii", "copies": 1, "atoms": 5_469, "style": "spacefill"}  # fmt: skip
    # Haines's counts (balls: the spheres and the floor) and the triangles raybench traces
    assert (by_name["balls 3"]["primitives"], by_name["balls 3"]["triangles"]) == (821, 2)
    assert (by_name["tetra 3"]["primitives"], by_name["tetra 3"]["triangles"]) == (64, 64)
    # 2 faces of 144 vertices, 144 rectangles and the ground square: 2 * 142 + 144 * 2 + 2
    assert (by_name["gears 1"]["primitives"], by_name["gears 1"]["triangles"]) == (147, 574)


def test_the_full_points_on_every_device_asked_for():
    points = suites.points(["scenes"], ["cpu", "cuda"], cores=2, accels=("bvh",))
    on_cpu = {p.options["scene"]: p for p in points if p.device == "cpu" and "scene" in p.options}
    molecules = [p for p in points if p.device == "cpu" and "molecule" in p.options]
    assert {p.device for p in points} == {"cpu", "cuda"} and len(points) == 2 * (len(on_cpu) + len(molecules))
    # hundreds of thousands to millions of atoms: the example and its copies, each counted
    assert [(p.options["copies"], p.spheres) for p in molecules] == [
        (1, 5_469), (2, 10_938), (18, 98_442), (183, 1_000_827), (914, 4_998_666)]  # fmt: skip
    assert all(p.options["atoms"] == p.spheres for p in molecules)
    assert set(on_cpu) == {f"{name} {k}" for name in real.SCENES_NAMES for k in range(1, 7)}
    assert on_cpu["balls 5"].spheres == 66_430 and on_cpu["balls 6"].spheres == 597_871
    # 2,730 cylinders 14.8 radii long: 8 bands of 32 quads each; and the wall
    assert on_cpu["rings 6"].options["triangles"] == 2_730 * 8 * 64 + 2


def test_a_point_is_measured_from_its_scenes_own_view():
    point = suites.Point("scenes", "cpu", 48, 30, 10, {"accel": "bvh", "scene": "balls 1", "shading": "whitted",
                                                      "depth": 5, "shadow_samples": 1})  # fmt: skip
    record = runner.measure(point, runner.Scenes(0), 0.05)
    assert record["spheres"] == 10 and record["frame_ms"]["median"] > 0 and record["options"]["scene"] == "balls 1"
    scene = real.scene("balls 1")
    frame = raybench.render(scene, width=48, height=30, device="cpu", shading="whitted", depth=5)
    # the rays the runner's frames cast are those of a frame seen from the scene's view (not the default camera)
    assert record["rays"] == frame.rays
    # and its picture is that frame (a JPEG: within a few steps of it), which the record's rules take
    shown = np.asarray(Image.open(io.BytesIO(pictures.jpeg(record["picture"]))).convert("RGB"))
    assert shown.shape == frame.image.shape
    off = np.abs(shown.astype(int) - frame.image).mean()
    assert off < 8 and np.abs(shown.astype(int) - frame.image[::-1]).mean() > 2 * off  # not some other frame
    results.check_record({**record, "run": RUN}, "probe")
    with pytest.raises(RaybenchError, match="picture"):
        results.check_record({**record, "picture": "data:image/png;base64,AAAA", "run": RUN}, "probe")


def test_a_large_frame_is_made_small_for_its_record():
    image = np.zeros((1050, 1680, 3), np.uint8)
    image[:, 840:] = 200
    shown = Image.open(io.BytesIO(pictures.jpeg(pictures.thumbnail(image))))
    assert shown.size == (pictures.WIDTH, 200)
    halves = np.asarray(shown.convert("RGB")).astype(int)
    assert halves[:, :150].max() < 8 and halves[:, 170:].min() > 192


def test_the_growth_of_a_frame_with_the_sphere_count():
    assert slope([(10, 1.0), (100, 10.0), (1000, 100.0)]) == pytest.approx(1.0)
    assert slope([(10, 2.0), (1000, 20.0)]) == pytest.approx(0.5)
    assert slope([(10, 2.0)]) is None


def record(device, scene, spheres, ms):
    return {"suite": "scenes", "device": device, "width": 320, "height": 200, "spheres": spheres,
            "options": {"scene": scene, "primitives": spheres + 1, "triangles": 2}, "frame_ms": {"median": ms},
            "rays_per_s": 1e6}  # fmt: skip


def test_the_verdicts_give_the_growth_and_the_gpus_lead():
    records = [record("cpu", "balls 1", 10, 10.0), record("cpu", "balls 3", 1000, 100.0),
               record("cuda", "balls 1", 10, 1.0), record("cuda", "balls 3", 1000, 4.0)]  # fmt: skip
    lines = verdicts(records)
    assert any(line.startswith("CPU: a frame's time grows as primitives^k") and "balls ^0.51 (11 to 1,001)" in line
               for line in lines)  # fmt: skip
    assert any("over the cpu on these scenes: median 17.5x (10.0x to 25.0x, 2 scenes)" in line for line in lines)


def test_the_section_gives_the_counts_and_names_old_records(tmp_path):
    out = []

    class Writer:
        def __call__(self, *lines):
            out.extend(lines)

    old = record("cpu", "balls 2", 91, 20.0)
    old["options"] = {"scene": "balls 2", "unrendered": "1 polygon"}  # before triangles were drawn
    _section_scenes(Writer(), "probe", "probe", [record("cpu", "balls 1", 10, 10.0), old])
    text = "\n".join(out)
    assert "| CPU | balls 1 | 11 | 10 | 2 |" in text and "| CPU | balls 2 | 91 | 91 | – |" in text
    assert "Records from before triangles were drawn (balls 2) traced the spheres alone." in text


def test_a_molecule_point_is_measured_from_its_own_view():
    point = suites.Point("scenes", "cpu", 32, 20, 10_938, {"accel": "bvh", "molecule": "1tii", "copies": 2,
                         "atoms": 10_938, "style": "spacefill", "shading": "whitted", "depth": 5,
                         "shadow_samples": 1})  # fmt: skip
    record = runner.measure(point, runner.Scenes(0), 0.05)
    assert record["spheres"] == 10_938 and record["options"]["copies"] == 2
    scene = real.molecule_scene("1tii", 2)
    frame = raybench.render(scene, width=32, height=20, device="cpu", shading="whitted", depth=5)
    assert record["rays"] == frame.rays


def molecule_record(device, copies, ms):
    return {"suite": "scenes", "device": device, "width": 320, "height": 200, "spheres": 5_469 * copies,
            "options": {"molecule": "1tii", "copies": copies, "atoms": 5_469 * copies, "style": "spacefill"},
            "frame_ms": {"median": ms}, "rays_per_s": 1e6}  # fmt: skip


def test_the_molecules_table_and_verdicts():
    out = []

    class Writer:
        def __call__(self, *lines):
            out.extend(lines)

    records = [molecule_record("cpu", 1, 10.0), molecule_record("cpu", 100, 20.0),
               molecule_record("cuda", 1, 2.0), molecule_record("cuda", 100, 2.0),
               record("cpu", "balls 1", 10, 10.0)]  # fmt: skip
    _section_scenes(Writer(), "probe", "probe", records)
    text = "\n".join(out)
    assert "### probe: molecules" in text and "| CPU | 1tii | 100 | 546,900 | 320x200 |" in text
    assert "| CPU | balls 1 | 11 | 10 | 2 |" in text  # the SPD's table still there
    lines = molecule_verdicts([r for r in records if "molecule" in r["options"]])
    assert any("CPU: a molecule's frame grows as atoms^k over its copies: 1tii ^0.15 (5,469 to 546,900 atoms)" in line
               for line in lines)  # fmt: skip
    assert any("over the cpu on the molecules: median 7.50x (5.00x to 10.0x, 2 points; 10.0x at 546,900 atoms)" in line
               for line in lines)  # fmt: skip


def test_the_section_shows_each_scenes_largest_frame(tmp_path):
    """One picture a scene and one a molecule, each its largest size's, a GPU's before the
    cpu's: files beside report.md, inlined in report.html; records without one show none."""
    from raybench.bench.report import html
    from raybench.bench.report.markdown_blocks import _Writer

    def drawn(r, level):
        return {**r, "picture": pictures.thumbnail(np.full((20, 32, 3), level, np.uint8))}

    records = [drawn(record("cpu", "balls 1", 10, 10.0), 10), drawn(record("cpu", "balls 3", 1000, 100.0), 20),
               drawn(record("cuda", "balls 3", 1000, 4.0), 30), record("cuda", "tetra 2", 64, 1.0),
               drawn(molecule_record("cuda", 2, 2.0), 40), drawn(molecule_record("cuda", 1, 2.0), 50)]  # fmt: skip
    w = _Writer(tmp_path)
    _section_scenes(w, "probe", "probe", records)
    text = "\n".join(w.lines)
    assert "![probe: balls 3, Whitted, on GPU](probe-scene-1.jpg)" in text and "probe-scene-2" not in text
    assert "![probe: 1tii, 10,938 atoms, Whitted, on GPU](probe-molecule-1.jpg)" in text
    levels = {
        name: np.asarray(Image.open(tmp_path / name)).mean() for name in ("probe-scene-1.jpg", "probe-molecule-1.jpg")
    }
    assert abs(levels["probe-scene-1.jpg"] - 30) < 3 and abs(levels["probe-molecule-1.jpg"] - 40) < 3
    page = html._details(w.lines, w.shown)
    assert page.count('src="data:image/jpeg;base64,') == 2 and "probe-scene-1.jpg" not in page
