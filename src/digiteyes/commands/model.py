"""``digiteyes model show|render``: inspect a model file and draw a posed model."""

from __future__ import annotations

from pathlib import Path

import click

from digiteyes.errors import ModelFileError
from digiteyes.kinematics import load_model

MAX_SIDE = 8192
"""Largest image side ``model render`` draws (pixels)."""


@click.group()
def model() -> None:
    """Inspect model files (shipped names or paths to .dh files)."""


@model.command("show")
@click.argument("model_name", metavar="MODEL")
def show(model_name: str) -> None:
    """Print the frame tree and the state layout of MODEL."""
    click.echo(load_model(model_name).describe())


@model.command("list")
def list_models() -> None:
    """List the shipped models."""
    from digiteyes.models import shipped_models

    for name in shipped_models():
        m = load_model(name)
        bodies = sum(link.kind in ("link", "palm") for link in m.links)
        click.echo(f"{name:<16} {m.n_q:>3} states  {bodies:>3} bodies  {m.description}")


@model.command("render")
@click.argument("model_name", metavar="MODEL")
@click.option("--state", "state_file", type=click.Path(dir_okay=False),
              help="JSON state file (default: the model's neutral state).")
@click.option("--view", default="front",
              help="front, back, side, top, bottom, oblique, or 'az,el[,dist]' in degrees/mm.")
@click.option("--style", type=click.Choice(["shaded", "wireframe"]), default="shaded")
@click.option("--size", default="640x480", help="Image size WxH in pixels.")
@click.option("-o", "--output", type=click.Path(dir_okay=False), default="model.png",
              show_default=True)
def render_model(model_name: str, state_file: str | None, view: str, style: str, size: str,
                 output: str) -> None:
    """Write a PNG of MODEL posed at a state, seen from any viewpoint (thesis Fig. 4.6)."""
    from digiteyes.kinematics import State
    from digiteyes.viz.model_view import write_model_png

    m = load_model(model_name)
    state = State(m) if state_file is None else State.load_json(m, state_file)
    try:
        width, height = (int(v) for v in size.lower().split("x"))
    except ValueError:
        raise click.BadParameter(f"expected WxH such as 640x480, got {size!r}") from None
    if not (1 <= width <= MAX_SIDE and 1 <= height <= MAX_SIDE):
        raise click.BadParameter(f"width and height must be 1 to {MAX_SIDE} pixels, got "
                                 f"{size!r}")
    if not any(link.kind in ("link", "palm", "tip") for link in m.links):
        raise ModelFileError(m.path or m.name, None, "the model has no geometry (no link, "
                             "palm or tip shapes) to draw")
    path = write_model_png(m, state.q, Path(output), view=view, style=style,
                           width=width, height=height)
    click.echo(f"wrote {path}")
