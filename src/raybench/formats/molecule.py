"""Molecules from PDB and mmCIF files: one sphere per atom, or balls and sticks.

Read by gemmi (the PDB's own format libraries' peer, maintained by CCP4 and
Global Phasing, one wheel without dependencies, reading PDB, mmCIF and their
gzipped files with the same call; biotite reads them too but brings more
than a reader). The first model only; of atoms with alternative locations,
the first conformer. Hydrogens are kept as the file has them unless
hydrogens=False, waters are left out unless waters=True.

Two styles: spacefill, each atom a sphere of its element's van der Waals
radius (Bondi's) in its element's CPK colour (Jmol's); ball-and-stick, each
atom a ball of BALL_SCALE of that radius and each bond (formats.bonds: the
file's connectivity and the covalent-radius rule) a stick of two halves in
its atoms' colours, the sticks as triangles: a scene of spheres and
triangles together. A biological assembly of the file's (assembly=, by name
or number) is built by gemmi; copies= repeats the molecule side by side in a
grid (formats.assemblies), for benchmarks of millions of atoms. The camera
is fitted to the atoms' bounds (formats.fit_camera), with one light over the
camera's shoulder for Whitted shading.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .. import lighting
from ..errors import RaybenchError
from ..scene import Scene
from . import assemblies, bonds, fit_camera

# Van der Waals radii in angstroms: A. Bondi, "van der Waals Volumes and
# Radii", J. Phys. Chem. 68 (1964) 441-451, table I (the values of his
# table, for the elements it gives; gemmi's own table, from the Blue
# Obelisk's, agrees but for platinum, which it gives as 1.75).
BONDI = {
    "H": 1.20, "He": 1.40, "Li": 1.82, "C": 1.70, "N": 1.55, "O": 1.52, "F": 1.47, "Ne": 1.54,
    "Na": 2.27, "Mg": 1.73, "Si": 2.10, "P": 1.80, "S": 1.80, "Cl": 1.75, "Ar": 1.88, "K": 2.75,
    "Ni": 1.63, "Cu": 1.40, "Zn": 1.39, "Ga": 1.87, "As": 1.85, "Se": 1.90, "Br": 1.85, "Kr": 2.02,
    "Pd": 1.63, "Ag": 1.72, "Cd": 1.58, "In": 1.93, "Sn": 2.17, "Te": 2.06, "I": 1.98, "Xe": 2.16,
    "Pt": 1.72, "Au": 1.66, "Hg": 1.55, "Tl": 1.96, "Pb": 2.02, "U": 1.86,
}  # fmt: skip
# Elements Bondi does not give (iron, calcium, most metals): this radius,
# near the middle of his table's, so that they are seen.
OTHER_RADIUS = 2.0
# CPK colours as Jmol draws them (jmol.sourceforge.net/jscolors, "Jmol's
# CPK colors"), 0xRRGGBB: the modern form of Corey, Pauling and Koltun's
# convention (grey carbon, where the original models' black would hide).
CPK = {
    "H": 0xFFFFFF, "He": 0xD9FFFF, "Li": 0xCC80FF, "B": 0xFFB5B5, "C": 0x909090, "N": 0x3050F8,
    "O": 0xFF0D0D, "F": 0x90E050, "Ne": 0xB3E3F5, "Na": 0xAB5CF2, "Mg": 0x8AFF00, "Al": 0xBFA6A6,
    "Si": 0xF0C8A0, "P": 0xFF8000, "S": 0xFFFF30, "Cl": 0x1FF01F, "Ar": 0x80D1E3, "K": 0x8F40D4,
    "Ca": 0x3DFF00, "Mn": 0x9C7AC7, "Fe": 0xE06633, "Co": 0xF090A0, "Ni": 0x50D050, "Cu": 0xC88033,
    "Zn": 0x7D80B0, "Se": 0xFFA100, "Br": 0xA62929, "Cd": 0xFFD98F, "I": 0x940094, "Pt": 0xD0D0E0,
    "Au": 0xFFD123, "Hg": 0xB8B8D0,
}  # fmt: skip
# Elements the table lacks: Jmol's colour for an unknown element.
OTHER_COLOUR = 0xFF1493
# Ball-and-stick: a ball's share of its atom's van der Waals radius, PyMOL's
# (its preset.ball_and_stick's sphere_scale; Jmol's default is 0.2).
BALL_SCALE = 0.25
STYLES = ("spacefill", "ball-and-stick")
# The light of a molecule: from above the camera, a little behind it.
LIGHT_RAISE = 0.5
BACKGROUND = (0.0, 0.0, 0.0)  # a molecule's background: PyMOL's


def radius(element: str) -> float:
    """An element's van der Waals radius in angstroms (Bondi's, else OTHER_RADIUS)."""
    return BONDI.get(_symbol(element), OTHER_RADIUS)


def colour(element: str) -> tuple[float, float, float]:
    """An element's CPK colour as rgb in [0, 1] (Jmol's, else OTHER_COLOUR)."""
    code = CPK.get(_symbol(element), OTHER_COLOUR)
    return ((code >> 16) / 255.0, ((code >> 8) & 0xFF) / 255.0, (code & 0xFF) / 255.0)


def _symbol(element: str) -> str:
    """'FE' or 'fe' as 'Fe'; deuterium is hydrogen."""
    text = element.strip().capitalize()
    return "H" if text == "D" else text


def atoms(path, hydrogens: bool = True, waters: bool = False) -> tuple[np.ndarray, list[str]]:
    """The first model's atoms in a PDB or mmCIF file: positions (n, 3)
    float64 in angstroms and element symbols, in the file's order."""
    found = read(path, hydrogens, waters)
    return found.positions, found.elements.tolist()


@dataclass(frozen=True)
class Molecule:
    """A molecule as read: name, its file's; positions (n, 3) float64 in angstroms;
    elements (n,) its atoms' symbols ('C', 'Fe'); bonds (b, 2) int64 pairs i < j,
    or None where not asked for; assembly, the name of the assembly built (None:
    the first model as it is); copies, of the molecule (or assembly) side by side;
    each, the atoms of one copy."""

    name: str
    positions: np.ndarray
    elements: np.ndarray
    bonds: np.ndarray | None
    assembly: str | None = None
    copies: int = 1
    each: int = 0

    def __len__(self) -> int:
        return len(self.positions)

    def notes(self) -> list[str]:
        """What is drawn beyond the file's first model, one line each: the assembly, the copies."""
        out = []
        if self.assembly is not None:
            out.append(f"note: {self.name}: biological assembly {self.assembly}, {self.each:,} atoms")
        if self.copies > 1:
            out.append(
                f"note: {self.name}: {self.copies:,} copies of its {self.each:,} atoms side by side in a grid, "
                f"{len(self):,} atoms: repeated for size, not chemistry"
            )
        return out

    def scene(self, style: str = "spacefill") -> Scene:
        """The Scene of the molecule drawn in `style` (STYLES)."""
        check_style(style)
        table = {e: (radius(e), colour(e)) for e in set(self.elements.tolist())}
        kinds, which = np.unique(self.elements, return_inverse=True)
        radii = np.array([table[e][0] for e in kinds.tolist()])[which]
        colours = np.array([table[e][1] for e in kinds.tolist()]).reshape(-1, 3)[which]
        meshes = []
        if style == "ball-and-stick":
            radii = BALL_SCALE * radii
            meshes = bonds.sticks(self.positions, self.elements, self.bonds, colour)
        camera = fit_camera(self.positions, radii)
        eye = np.array(camera.position)
        reach = np.linalg.norm(np.array(camera.look_at) - eye)
        light = lighting.Light(tuple((eye + np.array([0.0, LIGHT_RAISE * reach, 0.0])).tolist()))
        # on black, as PyMOL draws them: the thesis's gradient saturates past 1024 pixels across
        return Scene(self.positions, radii, colours, camera, lights=[light], meshes=meshes, background=BACKGROUND)


def check_style(style) -> str:
    if style not in STYLES:
        raise RaybenchError(f"--style: one of {', '.join(STYLES)}, got {style!r}")
    return style


def read(
    path, hydrogens: bool = True, waters: bool = False, assembly=None, copies: int = 1, bonded: bool = False
) -> Molecule:
    """The molecule of a PDB or mmCIF file: its first model, or the biological
    assembly named (or numbered from 1) `assembly`, repeated `copies` times side
    by side; with its bonds where bonded."""  # fmt: skip
    copies = assemblies.check_copies(copies)
    path = Path(path)
    structure = _structure(path)
    structure.remove_alternative_conformations()
    if not hydrogens:
        structure.remove_hydrogens()
    if not waters:
        structure.remove_waters()
    model = structure[0]
    # the atoms numbered in the file's order (their serials, which the bonds name),
    # the file's own serials kept for its CONECT records
    index_of_serial, elements, n = {}, [], 0
    for chain in model:
        for residue in chain:
            for atom in residue:
                index_of_serial.setdefault(atom.serial, n)
                atom.serial = n
                elements.append(_symbol(atom.element.name))
                n += 1
    if not n:
        left = [kind for kind, kept in (("waters", waters), ("hydrogens", hydrogens)) if not kept]
        left = f" (after leaving out {' and '.join(left)})" if left else ""
        raise RaybenchError(f"{path}: no atoms in its first model{left}")
    file_bonds = bonds.from_file(structure, model, index_of_serial) if bonded else None
    name = None
    if assembly is not None:
        chosen = assemblies.chosen(structure, assembly, str(path))
        name = chosen.name
        model, base, chains = assemblies.made(chosen, model, str(path))
        elements = [elements[i] for i in base.tolist()]
        if bonded:
            file_bonds = assemblies.carried(file_bonds, base, chains, n)
    elements = np.array(elements)
    positions = np.array([a.pos.tolist() for chain in model for residue in chain for a in residue], np.float64)
    found = None
    if bonded:
        found = bonds.ordered(np.concatenate([file_bonds, bonds.by_distance(model, elements)]))
    each = len(positions)
    if copies > 1:
        reach = max(radius(e) for e in set(elements.tolist()))
        offsets = assemblies.shifts(positions, reach, copies)
        positions, found = assemblies.repeated(positions, found, offsets)
        elements = np.tile(elements, copies)
    return Molecule(path.name, positions, elements, found, name, copies, each)


def _structure(path: Path):
    """The gemmi Structure of a file, with atoms in its first model; else one line."""
    import gemmi

    if not path.is_file():
        raise RaybenchError(f"{path}: no such molecule file" if not path.exists() else f"{path}: not a file")
    try:
        structure = gemmi.read_structure(str(path))
    except (RuntimeError, ValueError, OSError) as exc:
        structure = _old_pdb(gemmi, path)
        if structure is None:
            text = " ".join(str(exc).split())[:200]
            raise RaybenchError(f"{path}: cannot read it as PDB or mmCIF: {text}") from None
    if len(structure) == 0 or structure[0].count_atom_sites() == 0:
        raise RaybenchError(f"{path}: no atoms (no ATOM or HETATM records in a first model)")
    return structure


def _old_pdb(gemmi, path: Path):
    """A PDB file of the format before 1996 (PyMOL's own 1hpv.pdb): its columns 73-80 held the
    entry's code and the line's number, where the present format has the element and charge,
    which gemmi then refuses. Read to column 72, the elements taken from the atoms' names; None
    where that fails too or the file is no PDB."""
    if kind_of(path) != "pdb":
        return None
    try:
        return gemmi.read_pdb(str(path), max_line_length=72)
    except (RuntimeError, ValueError, OSError):
        return None


def kind_of(path: Path) -> str:
    """'cif' for an mmCIF file's suffix (gzipped or not), else 'pdb'."""
    name = path.name.lower().removesuffix(".gz")
    return "cif" if name.endswith((".cif", ".mmcif")) else "pdb"


def load(
    path, hydrogens: bool = True, waters: bool = False, style: str = "spacefill", assembly=None, copies: int = 1
) -> Scene:
    """The molecule in a PDB or mmCIF file as a Scene: one sphere per atom
    (spacefill), or balls and sticks (ball-and-stick: spheres and triangles);
    the biological assembly `assembly` (its name, or its number from 1) where
    given; `copies` of it side by side."""  # fmt: skip
    check_style(style)
    return read(path, hydrogens, waters, assembly, copies, bonded=style == "ball-and-stick").scene(style)
