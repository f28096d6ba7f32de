"""benchmarks/peers.py's own parts, without the peers: PyMOL's view of raybench's camera, the
copies of a molecule, POV-Ray's statistics read, and its refusals."""

import importlib.util
import os
import sys
from pathlib import Path

import numpy as np
import pytest
from test_molecules import write_pdb

from raybench import Camera
from raybench.formats import molecule

BENCHMARKS = Path(__file__).resolve().parent.parent / "benchmarks"


@pytest.fixture(scope="module")
def peers():
    sys.path.insert(0, str(BENCHMARKS))  # peers.py imports _harness and _embree beside it
    try:
        spec = importlib.util.spec_from_file_location("peers", BENCHMARKS / "peers.py")
        module = importlib.util.module_from_spec(spec)
        spec.loader.exec_module(module)
        yield module
    finally:
        sys.path.remove(str(BENCHMARKS))


def test_pymols_view_is_raybenchs_camera(peers):
    camera = Camera(position=(3.0, -2.0, 1.0), look_at=(0.5, 0.5, 9.0), up=(0.0, 0.0, 1.0), fov_deg=35.0)
    centres, radii = np.array([[0.0, 0.0, 9.0], [2.0, 1.0, 10.0]]), np.array([1.5, 1.0])
    view, rotation = peers.pymol_view(camera, centres, radii)
    assert len(view) == 18
    assert np.allclose(rotation @ rotation.T, np.eye(3)) and np.linalg.det(rotation) == pytest.approx(1.0)
    # the rotation, column by column, as PyMOL's view lists it
    assert np.allclose(np.array(view[:9]).reshape(3, 3).T, rotation)
    eye, at = np.array(camera.position), np.array(camera.look_at)
    forward = (at - eye) / np.linalg.norm(at - eye)
    assert np.allclose(rotation @ forward, [0.0, 0.0, -1.0])  # PyMOL looks down -z
    assert (rotation @ np.array(camera.up))[1] > 0  # up is up
    basis = camera.basis(100, 100)
    right = basis[2] / np.linalg.norm(basis[2])
    assert np.allclose(rotation @ right, [1.0, 0.0, 0.0], atol=1e-6)  # raybench's right is PyMOL's +x
    distance = np.linalg.norm(at - eye)
    assert view[9:12] == [0.0, 0.0, pytest.approx(-distance)] and np.allclose(view[12:15], at)
    nearest = min(np.linalg.norm(c - eye) - r for c, r in zip(centres, radii))
    farthest = max(np.linalg.norm(c - eye) + r for c, r in zip(centres, radii))
    assert 0 < view[15] < nearest and view[16] > farthest  # the clipping planes clear every sphere
    assert view[17] == -35.0  # perspective, the vertical field of view


def test_copies_of_a_molecule_have_every_atom_apart(peers, tmp_path):
    write_pdb(tmp_path / "m.pdb")
    one, elements = molecule.atoms(tmp_path / "m.pdb")
    name, path = peers.molecule_file(f"{tmp_path / 'm.pdb'}*3", tmp_path)
    assert name == f"{tmp_path / 'm.pdb'} x3"
    three, elements3 = molecule.atoms(path)
    assert len(three) == 3 * len(one) and elements3 == elements * 3
    # the copies side by side, none on another
    span = one.max(axis=0) - one.min(axis=0)
    assert np.allclose(three[len(one) : 2 * len(one), 0] - one[:, 0], span[0] + peers.COPY_GAP)


def test_a_molecule_not_found_is_named(peers, tmp_path):
    with pytest.raises(SystemExit, match="nosuch: no such file"):
        peers.molecule_file("nosuch", tmp_path)


def test_povrays_own_times_are_read(peers):
    stats = """Parser Time
  Parse Time:       0 hours  0 minutes  1 seconds (1.234 seconds)
  Bounding Time:    0 hours  0 minutes  0 seconds (0.056 seconds)
Render Time:
  Trace Time:       0 hours  0 minutes  2 seconds (2.500 seconds)
"""
    assert peers.povray_times(stats) == {"parse_s": 1.234, "bounding_s": 0.056, "trace_s": 2.5}
    assert peers.povray_times("no statistics") == {"parse_s": None, "bounding_s": None, "trace_s": None}


def test_the_zoomed_view_keeps_its_direction_and_halves_the_distance(peers, tmp_path):
    write_pdb(tmp_path / "m.pdb")
    scene = molecule.load(tmp_path / "m.pdb")
    zoomed = peers.black(scene, 2.0)
    at = np.array(scene.camera.look_at)
    before, after = np.array(scene.camera.position) - at, np.array(zoomed.camera.position) - at
    assert np.allclose(after, before / 2) and zoomed.camera.fov_deg == scene.camera.fov_deg
    assert zoomed.background == (0.0, 0.0, 0.0) and zoomed.lights == scene.lights
    assert peers.black(scene).camera == scene.camera


@pytest.mark.slow
def test_povray_side_by_side_end_to_end(tmp_path):
    """peers.py povray on a small SPD scene of triangles: both sides render the same picture
    (the silhouettes agree), and the records say which is which."""
    import json
    import shutil
    import subprocess

    if shutil.which("povray") is None:
        if os.environ.get("RAYBENCH_REQUIRE_POVRAY") == "1":
            pytest.fail("povray is not installed; RAYBENCH_REQUIRE_POVRAY=1 requires this test to run")
        pytest.skip("povray is not installed (Debian: apt-get install povray)")
    out = tmp_path / "povray.jsonl"
    argv = [sys.executable, str(BENCHMARKS / "peers.py"), "povray", "--scenes", "tetra:2", "--size", "64x40",
            "--frames", "1", "--rounds", "1", "--threads", "1", "--settle", "0", "--out", str(out),
            "--pictures", str(tmp_path / "pictures")]  # fmt: skip
    done = subprocess.run(argv, capture_output=True, text=True, timeout=900)
    assert done.returncode == 0, done.stderr[-2000:]
    records = [json.loads(line) for line in out.read_text().splitlines()]
    assert [r["quantity"] for r in records] == ["frame", "povray-render"]
    ours, theirs = records
    assert ours["options"]["scene"] == "tetra 2" and ours["values"]["triangles"] > 0
    assert theirs["values"]["silhouette_agree"] > 0.97
    assert (tmp_path / "pictures" / "tetra-2.png").exists()
