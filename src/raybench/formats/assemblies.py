"""A molecule's biological assemblies, and copies of it side by side.

An assembly is what the file says the molecule is in the cell (PDB's REMARK
350, mmCIF's pdbx_struct_assembly): its chains, each under the operators
that place its copies. gemmi's make_assembly builds it from the first model;
the file's own bonds (bonds.from_file) are carried into each copy of a chain
that holds both ends, and bonds between copies are left to the distance rule
(an inter-chain disulfide's 2.05 A is well within it).

Copies are no chemistry: the molecule (or its assembly) repeated in a grid
in the x-y plane, COPY_GAP apart, so that a benchmark reaches millions of
atoms from a small file; what is drawn says so (molecule.Molecule.notes, the
scenes suite's options).
"""

from __future__ import annotations

import math

import numpy as np

from ..errors import RaybenchError

# Room between copies, in angstroms, beyond their atoms' largest radius on each side.
COPY_GAP = 2.0
# The most copies: 5 million atoms of a 5,000-atom molecule need 1,000.
MAX_COPIES = 100_000


def names(structure) -> list[str]:
    """The file's assemblies' names, in its order."""
    return [a.name for a in structure.assemblies]


def chosen(structure, asked: str, where: str):
    """The gemmi Assembly named `asked`, or the asked-th (from 1) where no assembly has
    that name; else one line naming the assemblies the file has."""
    found = list(structure.assemblies)
    text = str(asked).strip()
    for assembly in found:
        if assembly.name == text:
            return assembly
    if text.isdigit() and 1 <= int(text) <= len(found):
        return found[int(text) - 1]
    if not found:
        raise RaybenchError(f"{where}: --assembly {text}: the file gives no biological assemblies")
    raise RaybenchError(f"{where}: --assembly {text}: no such assembly; the file has {', '.join(names(structure))}")


def made(assembly, model, where: str):
    """(the assembly's gemmi Model, base (m,) int64: each of its atoms' index in the
    model it was made from, chains: (start, end) of each chain copy), its atoms'
    serials numbered 0 to m - 1 in order. The model's serials must be its atoms'
    indices (molecule.read numbers them so)."""
    import gemmi

    built = gemmi.make_assembly(assembly, model, gemmi.HowToNameCopiedChain.Dup)
    base, chains, n = [], [], 0
    for chain in built:
        start = n
        for residue in chain:
            for atom in residue:
                base.append(atom.serial)
                atom.serial = n
                n += 1
        chains.append((start, n))
    if not n:
        raise RaybenchError(f"{where}: assembly {assembly.name} holds none of the atoms drawn")
    return built, np.array(base, np.int64), chains


def carried(file_bonds: np.ndarray, base: np.ndarray, chains, atoms: int) -> np.ndarray:
    """The file's bonds (pairs of the original model's atoms, `atoms` of them) in
    each chain copy that holds both of a bond's ends, as pairs of the assembly's."""
    if not len(file_bonds):
        return np.zeros((0, 2), np.int64)
    lookup = np.full(atoms, -1, np.int64)
    out = []
    for start, end in chains:
        lookup[base[start:end]] = np.arange(start, end)
        mapped = lookup[file_bonds]
        out.append(mapped[(mapped >= 0).all(axis=1)])
        lookup[base[start:end]] = -1
    return np.concatenate(out)


def check_copies(copies) -> int:
    """--copies, a whole number from 1 to MAX_COPIES, or one line."""
    if isinstance(copies, bool) or not isinstance(copies, (int, np.integer)) or not 1 <= copies <= MAX_COPIES:
        raise RaybenchError(f"--copies: a whole number from 1 to {MAX_COPIES:,}, got {copies!r}")
    return int(copies)


def grid(copies: int) -> tuple[int, int]:
    """(columns, rows) of the copies' grid: as square as the count allows."""
    columns = math.ceil(math.sqrt(copies))
    return columns, math.ceil(copies / columns)


def shifts(positions: np.ndarray, reach: float, copies: int) -> np.ndarray:
    """(copies, 3) offsets of the copies: a grid in the x-y plane, row by row, each
    step the atoms' extent and 2 * reach (their largest radius) and COPY_GAP, so that
    no atom of one copy touches another's; the first copy stays where it is."""
    step = positions.max(axis=0) - positions.min(axis=0) + 2 * reach + COPY_GAP
    columns, _ = grid(copies)
    k = np.arange(copies)
    out = np.zeros((copies, 3))
    out[:, 0] = step[0] * (k % columns)
    out[:, 1] = step[1] * (k // columns)
    return out


def repeated(positions: np.ndarray, bonds: np.ndarray | None, offsets: np.ndarray):
    """The positions (k * n, 3) and bonds (k * b, 2) of k copies at the offsets, copy by copy."""
    n = len(positions)
    placed = (positions[None, :, :] + offsets[:, None, :]).reshape(-1, 3)
    if bonds is None:
        return placed, None
    steps = (np.arange(len(offsets), dtype=np.int64) * n)[:, None, None]
    return placed, (bonds[None, :, :] + steps).reshape(-1, 2)
