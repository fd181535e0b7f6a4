"""``digiteyes prior fit``: learn a finger configuration space (Huang Sec. 2) from
joint-angle recordings."""

from __future__ import annotations

from pathlib import Path

import click

from digiteyes.kinematics import load_model


@click.group()
def prior() -> None:
    """Configuration-space priors for the divide-and-conquer tracker (Huang et al.)."""


@prior.command("fit")
@click.argument("files", nargs=-1, required=True, type=click.Path(dir_okay=False))
@click.option("-o", "--output", type=click.Path(dir_okay=False), required=True,
              help="The .npz file to write.")
@click.option("--model", "model_name", default="cardboard-hand", show_default=True,
              help="Model whose finger states the recordings are mapped to.")
@click.option("--dims", default=7, show_default=True, type=click.IntRange(1, 40),
              help="PCA dimensions kept (Huang: 7).")
def fit(files: tuple[str, ...], output: str, model_name: str, dims: int) -> None:
    """Fit a PCA prior to CyberGlove-style recordings FILES (.mat, .npy or .csv with the
    23 glove DOF) and print the variance kept per dimension."""
    from digiteyes.smc.prior import fit_glove_prior

    space = fit_glove_prior([Path(f) for f in files], load_model(model_name), dims)
    path = space.save(output)
    kept = space.kept_variance()
    total = space.variances.sum()
    click.echo(f"{space.source}; {len(space.joint_names)} finger joints of {model_name}")
    click.echo("dim  variance (rad^2)  share   cumulative")
    for d in range(len(kept)):
        mark = "*" if d < dims else " "
        share = space.variances[d] / total
        click.echo(f"{d + 1:>3}{mark} {space.variances[d]:>14.5f}  {share:6.1%}"
                   f"  {kept[d]:8.1%}")
    click.echo(f"kept {dims} dimensions: {kept[dims - 1]:.1%} of the variance")
    click.echo(f"wrote {path}")
