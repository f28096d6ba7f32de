"""Molecules (raybench.formats.molecule): a PDB file and its mmCIF, written
here, as one sphere per atom with Bondi's radius and Jmol's CPK colour;
hydrogens and waters as asked, the first model, the first conformer, and
a camera that sees every atom."""

import math

import numpy as np
import pytest
from test_cli import assert_user_error, cli

from raybench.errors import RaybenchError
from raybench.formats import molecule

# (record, atom name, alternate location, residue, residue number, x, y, z, element)
ATOMS = [
    ("ATOM", " N  ", " ", "ALA", 1, 11.104, 6.134, -6.504, "N"),
    ("ATOM", " CA ", " ", "ALA", 1, 11.639, 6.071, -5.147, "C"),
    ("ATOM", " C  ", " ", "ALA", 1, 13.149, 5.879, -5.222, "C"),
    ("ATOM", " O  ", " ", "ALA", 1, 13.716, 5.243, -6.108, "O"),
    ("ATOM", " CB ", "A", "ALA", 1, 11.285, 7.331, -4.367, "C"),
    ("ATOM", " CB ", "B", "ALA", 1, 10.285, 8.331, -3.367, "C"),  # a second conformer: left out
    ("ATOM", " H  ", " ", "ALA", 1, 10.500, 5.300, -6.900, "H"),
    ("ATOM", " SG ", " ", "CYS", 2, 14.000, 4.000, -4.000, "S"),
    ("HETATM", "FE  ", " ", "HEM", 3, 9.000, 9.000, -9.000, "FE"),
    ("HETATM", " O  ", " ", "HOH", 4, 20.000, 1.000, 2.000, "O"),  # a water
]


def pdb_line(serial, record, name, alt, residue, number, x, y, z, element, occupancy=1.0):
    """One ATOM or HETATM record in the PDB's fixed columns (format 3.3)."""
    return (f"{record:<6}{serial:>5} {name}{alt}{residue:>3} A{number:>4}    {x:8.3f}{y:8.3f}{z:8.3f}"
            f"{occupancy:6.2f}{0.0:6.2f}          {element:>2}")  # fmt: skip


def write_pdb(path, atoms=ATOMS, second_model=False):
    lines = ["MODEL        1"] if second_model else []
    for serial, atom in enumerate(atoms, 1):
        occupancy = 0.5 if atom[2] != " " else 1.0
        lines.append(pdb_line(serial, *atom, occupancy=occupancy))
    if second_model:
        lines += ["ENDMDL", "MODEL        2"]
        lines += [pdb_line(99, "ATOM", " N  ", " ", "GLY", 9, 0.0, 0.0, 0.0, "N"), "ENDMDL"]
    path.write_text("\n".join(lines + ["END", ""]))
    return path


def test_radii_and_colours_from_the_tables():
    assert molecule.radius("C") == 1.70 and molecule.radius("N") == 1.55 and molecule.radius("O") == 1.52
    assert molecule.radius("H") == 1.20 and molecule.radius("S") == 1.80 and molecule.radius("D") == 1.20
    assert molecule.radius("FE") == molecule.OTHER_RADIUS  # Bondi gives no iron
    assert molecule.colour("C") == pytest.approx((0x90 / 255,) * 3)
    assert molecule.colour("O") == pytest.approx((1.0, 13 / 255, 13 / 255))
    assert molecule.colour("N") == pytest.approx((0x30 / 255, 0x50 / 255, 0xF8 / 255))
    assert molecule.colour("Fe") == pytest.approx((0xE0 / 255, 0x66 / 255, 0x33 / 255))
    assert molecule.colour("Xx") == pytest.approx((1.0, 0x14 / 255, 0x93 / 255))


def test_one_sphere_per_atom(tmp_path):
    scene = molecule.load(write_pdb(tmp_path / "tiny.pdb"))
    # 10 atoms less the second conformer and the water
    assert len(scene) == 8
    assert scene.centers[0] == pytest.approx((11.104, 6.134, -6.504))
    elements = ["N", "C", "C", "O", "C", "H", "S", "Fe"]
    assert scene.radii.tolist() == pytest.approx([molecule.radius(e) for e in elements])
    assert scene.colors == pytest.approx(np.array([molecule.colour(e) for e in elements]), abs=1e-7)
    assert scene.centers[4] == pytest.approx((11.285, 7.331, -4.367))  # conformer A
    assert len(scene.lights) == 1


def test_hydrogens_and_waters_as_asked(tmp_path):
    path = write_pdb(tmp_path / "tiny.pdb")
    assert len(molecule.load(path, hydrogens=False)) == 7
    with_water = molecule.load(path, waters=True)
    assert len(with_water) == 9 and with_water.centers[-1] == pytest.approx((20.0, 1.0, 2.0))
    assert len(molecule.load(path, hydrogens=False, waters=True)) == 8


def test_the_first_model_only(tmp_path):
    assert len(molecule.load(write_pdb(tmp_path / "models.pdb", second_model=True))) == 8


def test_mmcif_gives_the_same_spheres(tmp_path):
    import gemmi

    structure = gemmi.read_structure(str(write_pdb(tmp_path / "tiny.pdb")))
    structure.setup_entities()
    structure.make_mmcif_document().write_file(str(tmp_path / "tiny.cif"))
    a, b = molecule.load(tmp_path / "tiny.pdb"), molecule.load(tmp_path / "tiny.cif")
    assert np.array_equal(a.spheres, b.spheres)


def test_the_camera_sees_every_atom(tmp_path):
    scene = molecule.load(write_pdb(tmp_path / "tiny.pdb"))
    camera = scene.camera
    eye = np.array(camera.position)
    forward = np.subtract(camera.look_at, eye)
    forward /= np.linalg.norm(forward)
    widest = 0.0
    for c, r in zip(scene.centers.astype(float), scene.radii.astype(float)):
        to = c - eye
        d = np.linalg.norm(to)
        widest = max(widest, math.degrees(math.acos(to @ forward / d) + math.asin(r / d)))
    assert camera.fov_deg / 2 * 0.6 < widest < camera.fov_deg / 2  # framed: all in view, not lost in it


def test_a_file_without_atoms_is_one_line(tmp_path):
    path = tmp_path / "water.pdb"
    write_pdb(path, [a for a in ATOMS if a[3] == "HOH"])
    with pytest.raises(RaybenchError, match=r"no atoms in its first model \(after leaving out waters\)"):
        molecule.load(path)
    (tmp_path / "empty.pdb").write_text("HEADER    NOTHING\nEND\n")
    with pytest.raises(RaybenchError, match="empty.pdb: no atoms"):
        molecule.load(tmp_path / "empty.pdb")
    with pytest.raises(RaybenchError, match="no such molecule file"):
        molecule.load(tmp_path / "absent.cif")


def test_render_a_molecule(capsys, tmp_path):
    path = write_pdb(tmp_path / "tiny.pdb")
    code, out, err = cli(capsys, "render", "--scene", path, "--no-hydrogens", "--size", "40x30", "--device", "cpu",
                         "--threads", 1, "-o", tmp_path / "tiny.png")  # fmt: skip
    assert code == 0, err
    assert "7 spheres" in out and (tmp_path / "tiny.png").exists()
    code, out, err = cli(capsys, "render", "--spheres", 5, "--waters", "-o", tmp_path / "x.png")
    assert_user_error(code, out, err, "--waters, --style, --assembly and --copies apply to a molecule file")


def test_a_pdb_file_of_the_old_format_reads_its_elements_from_the_atom_names(tmp_path):
    """Before 1996 columns 73-80 held the entry's code and the line's number (PyMOL's own
    1hpv.pdb): gemmi refuses them as an element and a charge; raybench reads to column 72."""
    lines = []
    for serial, atom in enumerate(ATOMS[:4] + ATOMS[7:8], 1):
        line = pdb_line(serial, *atom)[:66]
        lines.append(f"{line:<72}1ABC{180 + serial:>4}")
    path = tmp_path / "old.pdb"
    path.write_text("\n".join(lines) + "\nEND\n")
    positions, elements = molecule.atoms(path)
    assert elements == ["N", "C", "C", "O", "S"]
    assert positions[0].tolist() == [11.104, 6.134, -6.504]


def test_an_mmcif_file_is_not_retried_as_an_old_pdb(tmp_path):
    """The retry is for PDB files only: the same old lines named .cif are refused, in one line."""
    lines = [f"{pdb_line(1, *ATOMS[0])[:66]:<72}1ABC 181"]
    path = tmp_path / "old.cif"
    path.write_text("\n".join(lines) + "\nEND\n")
    with pytest.raises(RaybenchError, match="cannot read it as PDB or mmCIF"):
        molecule.atoms(path)
