"""A molecule's bonds, and its sticks for the ball-and-stick drawing.

Bonds are the union of two sources:

- the file's own connectivity, where it gives one: PDB CONECT records and the
  covalent links of LINK/SSBOND (mmCIF's struct_conn of types covale and
  disulf; metal coordination and hydrogen bonds are not covalent bonds and
  are left out, as are links to a symmetry mate, which are not in the model);
- the covalent-radius rule for the rest: two atoms are bonded where they are
  closer than the sum of their covalent radii (Cordero et al., "Covalent radii
  revisited", Dalton Trans. 2008, 2832-2838: gemmi's Element.covalent_r) and
  BOND_TOLERANCE, and no closer than MIN_BOND, as Jmol's autobonding does.

The candidate pairs come from gemmi's ContactSearch over its NeighborSearch
grid: the same maintained library that reads the file, in C++, so that a
model of a million atoms is searched in about a second. Its chemistry-aware
alternative (setup_entities + prepare_topology) needs the CCP4 monomer
library, which no wheel ships. Atoms left out (waters, hydrogens) are not in
the model searched, so no bond reaches them.

Sticks: each bond is two cylinders of STICK_RADIUS, from each atom's centre
to the bond's midpoint, in that atom's colour (Jmol's and PyMOL's default
colouring of sticks), made into triangles by polygons.cones; open cylinders
suffice, as their ends lie inside the atoms' balls or against the other
half's.
"""

from __future__ import annotations

import numpy as np

# Jmol's bondTolerance and minBondDistance (its defaults, in angstroms).
BOND_TOLERANCE = 0.45
MIN_BOND = 0.4
# PyMOL's ball-and-stick preset (preset.ball_and_stick, mode 1): a stick's radius in
# angstroms; the balls' share of the van der Waals radius is molecule.BALL_SCALE.
STICK_RADIUS = 0.14
# Quads around a stick: a stick is thin and its normals smooth, so 12 keep its
# silhouette within 1 - cos(pi / 12) of 0.14 A (0.005 A) for 48 triangles a bond.
STICK_SEGMENTS = 12


def covalent_radius(element: str) -> float:
    """An element's covalent radius in angstroms (Cordero's, as gemmi gives it; 0 for
    an unknown element, which then bonds by the file's connectivity only)."""
    import gemmi

    return float(gemmi.Element(element).covalent_r)


def longest(a: str, b: str) -> float:
    """The longest bond the distance rule makes between elements a and b."""
    return covalent_radius(a) + covalent_radius(b) + BOND_TOLERANCE


def by_distance(model, elements: np.ndarray) -> np.ndarray:
    """(b, 2) int64 pairs i < j of the model's atoms bonded by the covalent-radius
    rule; an atom's index is its serial, which the caller numbers 0 to n - 1."""
    import gemmi

    kinds = sorted(set(elements.tolist()))
    if not len(elements) or not kinds:
        return np.zeros((0, 2), np.int64)
    reach = max(covalent_radius(e) for e in kinds) * 2 + BOND_TOLERANCE
    # an empty unit cell: no symmetry mates, only the atoms of the model itself
    grid = gemmi.NeighborSearch(model, gemmi.UnitCell(), max(reach, 1.0)).populate()
    search = gemmi.ContactSearch(reach)
    search.ignore = gemmi.ContactSearch.Ignore.Nothing
    found = search.find_contacts(grid)
    if not found:
        return np.zeros((0, 2), np.int64)
    pairs = np.array([(c.partner1.atom.serial, c.partner2.atom.serial) for c in found], np.int64)
    dist = np.array([c.dist for c in found])
    radius = np.array([covalent_radius(e) for e in kinds])
    which = np.searchsorted(kinds, elements)
    r = radius[which]
    limit = r[pairs[:, 0]] + r[pairs[:, 1]] + BOND_TOLERANCE
    # an element without a covalent radius (gemmi's 0) is bonded by the file alone
    keep = (dist < limit) & (dist >= MIN_BOND) & (r[pairs[:, 0]] > 0) & (r[pairs[:, 1]] > 0)
    return ordered(pairs[keep])


def from_file(structure, model, index_of_serial: dict) -> np.ndarray:
    """(b, 2) int64 pairs of the file's own bonds among the model's atoms: CONECT
    (by the file's serial numbers, index_of_serial mapping them to the atoms kept)
    and the covalent connections (LINK, SSBOND, struct_conn covale and disulf)
    within the model; an end that was left out drops its bond."""
    import gemmi

    pairs = []
    for serial, partners in structure.conect_map.items():
        a = index_of_serial.get(serial)
        for partner in partners:
            b = index_of_serial.get(partner)
            if a is not None and b is not None and a != b:
                pairs.append((a, b))
    covalent = (gemmi.ConnectionType.Covale, gemmi.ConnectionType.Disulf)
    for link in structure.connections:
        if link.type not in covalent or link.asu == gemmi.Asu.Different:
            continue
        ends = [model.find_cra(link.partner1), model.find_cra(link.partner2)]
        if all(end.atom is not None for end in ends):
            pairs.append((ends[0].atom.serial, ends[1].atom.serial))
    return ordered(np.array(pairs, np.int64).reshape(-1, 2))


def ordered(pairs: np.ndarray) -> np.ndarray:
    """Pairs as (low, high), each once, sorted."""
    pairs = np.sort(np.asarray(pairs, np.int64).reshape(-1, 2), axis=1)
    pairs = pairs[pairs[:, 0] != pairs[:, 1]]
    return np.unique(pairs, axis=0) if len(pairs) else pairs


def halves(positions: np.ndarray, bonds: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Each bond's two halves as cones' rows (2b, 8): from an atom's centre to the
    midpoint, STICK_RADIUS at both ends, the first end's half first; and (2b,) the
    atom each half belongs to (its colour's)."""
    a, b = positions[bonds[:, 0]], positions[bonds[:, 1]]
    middle = (a + b) / 2
    r = np.full((len(bonds), 1), STICK_RADIUS)
    rows = np.empty((2 * len(bonds), 8))
    rows[0::2] = np.hstack([a, r, middle, r])
    rows[1::2] = np.hstack([b, r, middle, r])
    owner = np.empty(2 * len(bonds), np.int64)
    owner[0::2], owner[1::2] = bonds[:, 0], bonds[:, 1]
    return rows, owner


def sticks(positions: np.ndarray, elements: np.ndarray, bonds: np.ndarray, colour) -> list:
    """The SceneMeshes of the bonds' halves: one for each element (its colour,
    colour(element)), of smooth cylinders STICK_SEGMENTS quads round."""
    from ..meshes import Mesh
    from ..scene_meshes import SceneMesh
    from . import polygons

    if not len(bonds):
        return []
    rows, owner = halves(positions, bonds)
    kinds, which = np.unique(elements[owner], return_inverse=True)
    out = []
    for k, element in enumerate(kinds.tolist()):
        mine = rows[which == k]
        tri = polygons.cones(mine, np.zeros(len(mine), np.int32), STICK_SEGMENTS)
        n = len(tri)
        vertices = tri.corners.reshape(-1, 3).astype(np.float32)
        faces = np.arange(3 * n, dtype=np.int32).reshape(n, 3)
        normals = tri.normals.reshape(-1, 3).astype(np.float32)
        out.append(SceneMesh(Mesh(vertices, faces, normals), colour(element)))
    return out
