"""``digiteyes track``: placeholder until its issue lands."""

from __future__ import annotations

import click


@click.command()
def track() -> None:
    """Not implemented yet."""
    raise click.ClickException("'digiteyes track' is not implemented yet")
