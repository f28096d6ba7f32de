"""The options of a molecule file (--no-hydrogens, --waters, --style, --assembly, --copies),
written once for render and view, and their record, MoleculeArgs, which the loader takes."""

from __future__ import annotations

from dataclasses import dataclass

import click

from ..errors import RaybenchError

MOLECULE_ONLY = (
    "--no-hydrogens, --waters, --style, --assembly and --copies apply to a molecule file "
    "(--scene FILE.pdb or .cif, or --scene 1tii) only"
)


@dataclass(frozen=True)
class MoleculeArgs:
    """--no-hydrogens, --waters: which atoms of a molecule file are drawn; --style, how
    (None: spacefill); --assembly, which biological assembly (None: the first model as it
    is); --copies, how many side by side (None: one). None where not given, so that any
    given to a scene that is no molecule is refused."""

    hydrogens: bool = True
    waters: bool = False
    style: str | None = None
    assembly: str | None = None
    copies: int | None = None

    def load(self, path):
        """The Scene of the molecule file at path, drawn as these options ask; its notes
        (an assembly built, copies made) said on stdout."""
        from ..formats import molecule

        style = molecule.check_style(self.style or "spacefill")
        copies = 1 if self.copies is None else self.copies
        found = molecule.read(
            path, self.hydrogens, self.waters, self.assembly, copies, bonded=style == "ball-and-stick"
        )
        for note in found.notes():
            click.echo(note)
        return found.scene(style)


def refuse_unless_molecule(molecule: MoleculeArgs | None) -> None:
    """One line where molecule options were given to a scene that is no molecule."""
    if molecule is not None and molecule != MoleculeArgs():
        raise RaybenchError(MOLECULE_ONLY)


def molecule_options():
    """The click options of a molecule file, in the order --help shows them."""
    return [
        click.option("--no-hydrogens", is_flag=True, help="a molecule file: leave out its hydrogen atoms"),
        click.option("--waters", is_flag=True, help="a molecule file: draw its waters too (left out by default)"),
        click.option(
            "--style",
            type=click.Choice(("spacefill", "ball-and-stick")),
            help="a molecule file: spacefill (the default), each atom a sphere of its van der Waals radius; "
            "ball-and-stick, balls of a quarter of it and each bond a stick, half in each atom's colour",
        ),
        click.option(
            "--assembly",
            help="a molecule file: draw the biological assembly of this name (or number, from 1) that the file "
            "gives (PDB REMARK 350, mmCIF pdbx_struct_assembly)",
        ),
        click.option(
            "--copies",
            type=int,
            help="a molecule file: K copies of the molecule (or its assembly) side by side in a grid, for "
            "benchmarks of millions of atoms (default 1)",
        ),
    ]
