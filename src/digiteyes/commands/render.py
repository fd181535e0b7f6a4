"""``digiteyes render``: render a synthetic scenario into a sequence folder with ground truth."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import click

from digiteyes.errors import DigitEyesError
from digiteyes.synth.scenarios import SCENARIOS

HELP = f"""Render SCENARIO into the sequence folder DIR, with ground truth.

SCENARIO is one of: {", ".join(SCENARIOS)} (docs/scenarios.md). Every frame is rendered
through every camera of the scenario's rig and written with its true state, keypoints
(3D and per camera) and their visibility. The same SCENARIO, --seed and options give the
same dataset, so an interrupted render (Ctrl-C) continues with --resume.
"""


@click.command(help=HELP)
@click.argument("scenario_name", metavar="SCENARIO")
@click.option("-o", "--output", "output", required=True, metavar="DIR",
              type=click.Path(file_okay=False), help="Sequence folder to write.")
@click.option("--background", default="black", show_default=True,
              help="black (the thesis's black cloth), uniform, clutter, or an image file.")
@click.option("--color", is_flag=True, help="RGB images instead of grey levels.")
@click.option("--noise", type=click.FloatRange(min=0.0), default=0.0, show_default=True,
              metavar="SIGMA", help="Gaussian sensor noise, grey levels (0-255).")
@click.option("--blur", type=click.FloatRange(min=0.0), default=0.0, show_default=True,
              metavar="SIGMA", help="Gaussian blur, pixels.")
@click.option("--perturb", type=click.FloatRange(min=0.0, max=1.0, max_open=True), default=0.0,
              show_default=True, metavar="FRACTION",
              help="Render a 'true' hand whose link lengths differ from the model by up to "
                   "this fraction; model.dh stays the nominal tracking model.")
@click.option("--appearance", type=click.Choice(["model", "flesh"]), default="model",
              show_default=True, help="model: the tracking model's own solids; flesh: an "
              "independent hand surface (tapered, blended fingers, fleshy palm, textured "
              "skin, highlights; docs/appearance.md).")
@click.option("--skin-tone", type=click.Choice(["light", "medium", "olive", "brown", "dark"]),
              default=None, help="Named skin tone (default: the standard skin colour).")
@click.option("--shadows", is_flag=True, help="The hand casts shadows on itself (flesh).")
@click.option("--hand-scale", type=click.FloatRange(0.8, 1.15), default=1.0, show_default=True,
              metavar="F", help="Draw a hand F times the size of the tracking model "
              "(0.8-1.15 of Appendix A); model.dh stays the tracking model.")
@click.option("--frames", type=click.IntRange(min=1), default=None, metavar="N",
              help="Number of frames (default: the scenario's own length).")
@click.option("--seed", type=click.IntRange(min=0), default=0, show_default=True, metavar="S",
              help="Seed of the motion, the noise, the backdrop and the perturbation.")
@click.option("--video", is_flag=True, help="One lossless FFV1 video per camera, not PNGs.")
@click.option("--force", is_flag=True, help="Replace whatever DIR holds.")
@click.option("--resume", is_flag=True, help="Continue an interrupted render of DIR.")
def render(scenario_name: str, output: str, background: str, color: bool, noise: float,
           blur: float, perturb: float, appearance: str, skin_tone: str | None,
           shadows: bool, hand_scale: float, frames: int | None, seed: int, video: bool,
           force: bool, resume: bool) -> None:
    if force and resume:
        raise DigitEyesError("--force and --resume exclude each other: --force starts again, "
                             "--resume continues")
    from digiteyes.synth.scenarios import build_scenario
    from digiteyes.synth.sequence import render_scenario

    scenario = build_scenario(scenario_name, seed=seed, n_frames=frames)
    if hand_scale != 1.0:
        scenario = dataclasses.replace(scenario, metadata={**scenario.metadata,
                                                           "hand_scale": hand_scale})
    try:
        done = render_scenario(scenario, Path(output), seed=seed, background=background,
                               color=color, noise=noise, blur=blur, perturb=perturb,
                               video=video, force=force, resume=resume,
                               appearance=appearance, skin_tone=skin_tone, shadows=shadows)
    except KeyboardInterrupt:
        how = ("video sequences cannot be resumed: run the same command with --force to "
               "start again" if video else "run the same command with --resume to continue")
        click.echo(f"digiteyes render: stopped before the end of {scenario.n_frames} frames; "
                   f"{how}", err=True)
        raise
    click.echo(f"wrote {done.n_written} frame(s) x {len(scenario.rig)} camera(s) of "
               f"{scenario.name} (seed {seed}) to {done.folder}")
