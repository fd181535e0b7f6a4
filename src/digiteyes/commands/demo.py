"""``digiteyes demo``: placeholder until its issue lands."""

from __future__ import annotations

import click


@click.command()
def demo() -> None:
    """Not implemented yet."""
    raise click.ClickException("'digiteyes demo' is not implemented yet")
