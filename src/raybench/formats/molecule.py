"""Molecules from PDB and mmCIF files: one sphere per atom.

Read by gemmi (the PDB's own format libraries' peer, maintained by CCP4 and
Global Phasing, one wheel without dependencies, reading PDB, mmCIF and their
gzipped files with the same call; biotite reads them too but brings more
than a reader). The first model only; of atoms with alternative locations,
the first conformer. Each atom is a sphere of its element's van der Waals
radius (Bondi's) in its element's CPK colour (Jmol's); hydrogens are kept
as the file has them unless hydrogens=False, waters are left out unless
waters=True. The camera is fitted to the atoms' bounds (formats.fit_camera),
with one light over the camera's shoulder for Whitted shading.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from .. import lighting
from ..errors import RaybenchError
from ..scene import Scene
from . import fit_camera

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
# The light of a molecule: from above the camera, a little behind it.
LIGHT_RAISE = 0.5


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
    import gemmi

    path = Path(path)
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
    structure.remove_alternative_conformations()
    if not hydrogens:
        structure.remove_hydrogens()
    positions, elements = [], []
    for chain in structure[0]:
        for residue in chain:
            if not waters and residue.is_water():
                continue
            for atom in residue:
                p = atom.pos
                positions.append((p.x, p.y, p.z))
                elements.append(atom.element.name)
    if not positions:
        left = [kind for kind, kept in (("waters", waters), ("hydrogens", hydrogens)) if not kept]
        left = f" (after leaving out {' and '.join(left)})" if left else ""
        raise RaybenchError(f"{path}: no atoms in its first model{left}")
    return np.array(positions, np.float64), elements


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


def load(path, hydrogens: bool = True, waters: bool = False) -> Scene:
    """The molecule in a PDB or mmCIF file as a Scene: one sphere per atom."""
    positions, elements = atoms(path, hydrogens, waters)
    table = {e: (radius(e), colour(e)) for e in set(elements)}
    radii = np.array([table[e][0] for e in elements])
    colours = np.array([table[e][1] for e in elements])
    camera = fit_camera(positions, radii)
    eye = np.array(camera.position)
    reach = np.linalg.norm(np.array(camera.look_at) - eye)
    light = lighting.Light(tuple((eye + np.array([0.0, LIGHT_RAISE * reach, 0.0])).tolist()))
    return Scene(positions, radii, colours, camera, lights=[light])
