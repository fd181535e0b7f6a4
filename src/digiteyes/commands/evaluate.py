"""``digiteyes evaluate``: placeholder until its issue lands."""

from __future__ import annotations

import click


@click.command()
def evaluate() -> None:
    """Not implemented yet."""
    raise click.ClickException("'digiteyes evaluate' is not implemented yet")
