"""raybench schema: the results record's JSON Schema, as results.check_record applies it."""

from __future__ import annotations

import json

import click


@click.command(name="schema")
def schema_cmd():
    """Print the JSON Schema (draft 2020-12) of one line of a results file:
    the rules `raybench report` and `compare` apply, from the same checkers.
    A results file that a pull request adds under benchmarks/results/ must
    pass it (docs/results-schema.json is the same schema)."""
    from ..bench import results
    from .out import echo

    echo(json.dumps(results.schema(), indent=2))
