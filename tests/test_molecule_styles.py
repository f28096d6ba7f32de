"""Molecules drawn ball-and-stick, their assemblies and copies (raybench.formats.molecule,
bonds, assemblies), against references of their own: the shipped example 1TII's residues'
bonds by the amino acids' chemistry, its file's CONECT records, sticks' ends at their atoms,
assemblies' atom counts by gemmi's make_assembly, copies by translation, a ball-and-stick
frame's hits by the float64 reference of spheres and triangles, and the CLI's refusals."""

import gzip
from importlib import resources

import numpy as np
import pytest
from test_cli import assert_user_error, cli
from test_mixed import both_reference

from raybench import render
from raybench.errors import RaybenchError
from raybench.examples import path as example
from raybench.formats import assemblies, bonds, molecule, polygons

# Heavy-atom bonds within a residue of the standard amino acids (their chemistry, not the
# distance rule): the backbone's, then the side chain's.
BACKBONE = {("N", "CA"), ("CA", "C"), ("C", "O")}
SIDE = {
    "GLY": set(),
    "ALA": {("CA", "CB")},
    "SER": {("CA", "CB"), ("CB", "OG")},
    "CYS": {("CA", "CB"), ("CB", "SG")},
    "VAL": {("CA", "CB"), ("CB", "CG1"), ("CB", "CG2")},
    "THR": {("CA", "CB"), ("CB", "OG1"), ("CB", "CG2")},
    "PHE": {("CA", "CB"), ("CB", "CG"), ("CG", "CD1"), ("CG", "CD2"), ("CD1", "CE1"), ("CD2", "CE2"),
            ("CE1", "CZ"), ("CE2", "CZ")},
}  # fmt: skip


def shipped_lines() -> list[str]:
    with resources.as_file(example("1tii")) as path:
        return gzip.decompress(path.read_bytes()).decode().splitlines()


@pytest.fixture(scope="module")
def shipped():
    """The example read with its bonds, and its atoms' (chain, residue number, name, residue name) from
    the file's own lines, in the order drawn (ATOM and HETATM, waters left out, no alternates here)."""
    with resources.as_file(example("1tii")) as path:
        found = molecule.read(path, bonded=True)
    atoms = [(line[21], int(line[22:26]), line[12:16].strip(), line[17:20]) for line in shipped_lines()
             if line.startswith(("ATOM", "HETATM")) and line[17:20] != "HOH"]  # fmt: skip
    return found, atoms


def test_the_example_ships_and_reads(shipped):
    found, atoms = shipped
    assert len(found) == len(atoms) == 5_469 and found.name == "1tii.pdb.gz"
    assert len(molecule.read(example("1tii"), waters=True)) == 5_684  # every ATOM and HETATM record


def test_each_standard_residues_bonds_are_its_chemistrys(shipped):
    found, atoms = shipped
    pairs = {tuple(p) for p in found.bonds.tolist()}
    residues = {}
    for i, (chain, number, name, kind) in enumerate(atoms):
        residues.setdefault((chain, number, kind), {})[name] = i
    checked = 0
    for (_chain, _number, kind), names in residues.items():
        if "N" in names and "CA" in names and "C" in names and "O" in names:
            for a, b in BACKBONE:  # every standard residue's backbone
                assert tuple(sorted((names[a], names[b]))) in pairs, (kind, a, b)
        if kind in SIDE and set(names) == {n for pair in BACKBONE | SIDE[kind] for n in pair}:
            want = {tuple(sorted((names[a], names[b]))) for a, b in BACKBONE | SIDE[kind]}
            mine = set(names.values())
            inside = {p for p in pairs if p[0] in mine and p[1] in mine}
            assert inside == want, kind  # no bond missing, none extra
            checked += 1
    assert checked > 100


def test_peptide_bonds_join_the_chain(shipped):
    found, atoms = shipped
    pairs = {tuple(p) for p in found.bonds.tolist()}
    index = {(c, n, name): i for i, (c, n, name, _k) in enumerate(atoms)}
    joined = [(index[(c, n, "C")], index[(c, n + 1, "N")]) for (c, n, name) in index
              if name == "C" and (c, n + 1, "N") in index]  # fmt: skip
    near = [p for p in joined if np.linalg.norm(found.positions[p[0]] - found.positions[p[1]]) < 1.5]
    assert len(near) > 0.95 * len(joined) and all(tuple(sorted(p)) in pairs for p in near)


def test_no_bond_is_longer_than_the_rule_allows(shipped):
    found, _ = shipped
    file_bonds = {(int(line[6:11]), int(s)) for line in shipped_lines() if line.startswith("CONECT")
                  for s in line[11:31].split()}  # fmt: skip
    serial = {int(line[6:11]): i for i, line in enumerate(
        [x for x in shipped_lines() if x.startswith(("ATOM", "HETATM")) and x[17:20] != "HOH"])}  # fmt: skip
    given = {tuple(sorted((serial[a], serial[b]))) for a, b in file_bonds if a in serial and b in serial}
    assert given and given <= {tuple(p) for p in found.bonds.tolist()}  # the file's CONECT bonds are drawn
    e, p = found.elements, found.positions
    for i, j in found.bonds.tolist():
        d = np.linalg.norm(p[i] - p[j])
        assert (i, j) in given or bonds.MIN_BOND <= d < bonds.longest(e[i], e[j]), (i, j, d)


def test_the_sticks_ends_are_at_their_atoms_and_split_at_the_middle(shipped):
    found, _ = shipped
    b = found.bonds[:200]
    rows, owner = bonds.halves(found.positions, b)
    a, z = found.positions[b[:, 0]], found.positions[b[:, 1]]
    assert np.array_equal(rows[0::2, :3], a) and np.array_equal(rows[1::2, :3], z)
    assert np.allclose(rows[0::2, 4:7], (a + z) / 2) and np.allclose(rows[1::2, 4:7], (a + z) / 2)
    assert (rows[:, [3, 7]] == bonds.STICK_RADIUS).all()
    assert owner.tolist() == b.ravel().tolist()


def tiny():
    """Residues 1 to 3 of chain D and 1 to 2 of chain E of the example, as a PDB file's lines."""
    last = {"D": 3, "E": 2}
    return [line for line in shipped_lines() if line.startswith("ATOM") and int(line[22:26]) <= last.get(line[21], 0)]


def test_a_ball_and_stick_scene(tmp_path):
    path = tmp_path / "tiny.pdb"
    path.write_text("\n".join(tiny() + ["END", ""]))
    found = molecule.read(path, bonded=True)
    scene = molecule.load(path, style="ball-and-stick")
    spacefill = molecule.load(path)
    assert np.allclose(scene.radii, molecule.BALL_SCALE * spacefill.radii)
    # each half a cylinder of STICK_SEGMENTS quads round, in bands along it (polygons.bands)
    rows, owner = bonds.halves(found.positions, found.bonds)
    per_half = 2 * bonds.STICK_SEGMENTS * polygons.bands(rows)
    assert (per_half > 2 * bonds.STICK_SEGMENTS).all()  # a half bond is longer than a stick's diameter
    assert scene.triangles.shape[1] == per_half.sum()
    assert scene.traced().kind == "mixed"
    # each element's sticks are one mesh in its colour, as many halves as its atoms' bonds
    ends = found.elements[owner]
    for mesh in scene.meshes:
        element = next(e for e in set(ends.tolist()) if np.allclose(mesh.colour, molecule.colour(e)))
        assert len(mesh.mesh) == per_half[ends == element].sum()


def test_a_ball_and_stick_frame_hits_the_float64_reference(tmp_path):
    path = tmp_path / "chain.pdb"
    path.write_text("\n".join([line for line in tiny() if line[21] == "D"] + ["END", ""]))
    scene = molecule.load(path, style="ball-and-stick")
    frame = render(scene, None, 96, 64, device="cpu", threads=2)
    index, _t, clear, _o, _d = both_reference(scene, 96, 64)
    kinds = index[clear & (index >= 0)]
    assert (kinds < len(scene)).sum() > 20 and (kinds >= len(scene)).sum() > 20  # balls and sticks seen
    assert np.array_equal(frame.hits.ravel()[clear], index[clear])


REMARK_350 = """REMARK 350 BIOMOLECULE: 1
REMARK 350 APPLY THE FOLLOWING TO CHAINS: D, E
REMARK 350   BIOMT1   1  1.000000  0.000000  0.000000        0.00000
REMARK 350   BIOMT2   1  0.000000  1.000000  0.000000        0.00000
REMARK 350   BIOMT3   1  0.000000  0.000000  1.000000        0.00000
REMARK 350   BIOMT1   2 -1.000000  0.000000  0.000000      120.00000
REMARK 350   BIOMT2   2  0.000000 -1.000000  0.000000        0.00000
REMARK 350   BIOMT3   2  0.000000  0.000000  1.000000        0.00000
REMARK 350 BIOMOLECULE: 2
REMARK 350 APPLY THE FOLLOWING TO CHAINS: E
REMARK 350   BIOMT1   1  1.000000  0.000000  0.000000        0.00000
REMARK 350   BIOMT2   1  0.000000  1.000000  0.000000        0.00000
REMARK 350   BIOMT3   1  0.000000  0.000000  1.000000        0.00000""".splitlines()


@pytest.fixture
def assembled(tmp_path):
    path = tmp_path / "two.pdb"
    path.write_text("\n".join(REMARK_350 + tiny() + ["END", ""]))
    return path


def test_assemblies_have_gemmis_atoms(assembled):
    import gemmi

    structure = gemmi.read_structure(str(assembled))
    n = {a.name: gemmi.make_assembly(a, structure[0], gemmi.HowToNameCopiedChain.AddNumber).count_atom_sites()
         for a in structure.assemblies}  # fmt: skip
    assert set(n) == {"1", "2"}
    one, two = molecule.read(assembled, assembly="1", bonded=True), molecule.read(assembled, assembly=2)
    assert (len(one), len(two)) == (n["1"], n["2"]) == (2 * len(tiny()), sum(line[21] == "E" for line in tiny()))
    # the second copy is the first turned about z and moved 120 A along x; its bonds the same pairs
    base = molecule.read(assembled, bonded=True)
    half = len(base)
    assert np.allclose(one.positions[:half], base.positions)
    assert np.allclose(one.positions[half:], base.positions * [-1, -1, 1] + [120, 0, 0])
    assert len(one.bonds) == 2 * len(base.bonds)
    assert one.notes() == [f"note: two.pdb: biological assembly 1, {len(one):,} atoms"]


def test_a_missing_assembly_is_refused_naming_the_files(assembled, tmp_path):
    with pytest.raises(RaybenchError, match=r"--assembly 3: no such assembly; the file has 1, 2$"):
        molecule.read(assembled, assembly="3")
    plain = tmp_path / "plain.pdb"
    plain.write_text("\n".join(tiny() + ["END", ""]))
    with pytest.raises(RaybenchError, match="--assembly 1: the file gives no biological assemblies"):
        molecule.read(plain, assembly="1")


def test_copies_are_translations_apart(tmp_path):
    path = tmp_path / "tiny.pdb"
    path.write_text("\n".join(tiny() + ["END", ""]))
    base = molecule.read(path, bonded=True)
    k, n = 5, len(base)
    copies = molecule.read(path, copies=k, bonded=True)
    assert len(copies) == k * n and len(copies.bonds) == k * len(base.bonds) and copies.each == n
    assert np.array_equal(copies.bonds[-len(base.bonds) :], base.bonds + (k - 1) * n)
    parts = copies.positions.reshape(k, n, 3)
    reach = max(molecule.radius(e) for e in set(base.elements.tolist()))
    for c in range(k):
        moved = parts[c] - base.positions
        assert np.allclose(moved, moved[0])  # each copy the molecule moved, not turned
        for d in range(c):  # no atom of one copy touches another's
            gap = np.linalg.norm(parts[c][:, None] - parts[d][None], axis=2).min()
            assert gap > 2 * reach
    assert assemblies.grid(k) == (3, 2) and "5 copies of its" in copies.notes()[0]
    with pytest.raises(RaybenchError, match="--copies: a whole number from 1 to 100,000, got 0"):
        molecule.read(path, copies=0)


def test_the_cli_draws_the_example_and_refuses_in_one_line(capsys, tmp_path):
    code, out, err = cli(capsys, "render", "--scene", "1tii", "--copies", 2, "--size", "32x24", "--device", "cpu",
                         "--threads", 1, "-o", tmp_path / "two.png")  # fmt: skip
    assert code == 0, err
    assert "10,938 spheres" in out and "2 copies of its 5,469 atoms" in out
    for args, needle in [
        (("--spheres", 5, "--style", "ball-and-stick"), "--style, --assembly and --copies apply to a molecule"),
        (("--scene", "whitted", "--copies", 2), "apply to a molecule file"),
        (("--scene", "1tii", "--copies", 0), "--copies: a whole number from 1"),
        (("--scene", "1tii", "--assembly", "2"), "--assembly 2: the file gives no biological assemblies"),
    ]:
        code, out, err = cli(capsys, "render", *args, "--device", "cpu", "-o", tmp_path / "x.png")
        assert_user_error(code, out, err, needle)
