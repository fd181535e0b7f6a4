"""``digiteyes render``: render a synthetic scenario into a sequence folder with ground truth."""

from __future__ import annotations

import json
from pathlib import Path

import click
import numpy as np

from digiteyes.errors import DigitEyesError
from digiteyes.synth.scenarios import SCENARIOS

HELP = f"""Render SCENARIO into the sequence folder DIR, with ground truth.

SCENARIO is one of: {", ".join(SCENARIOS)} (docs/scenarios.md). Every frame is rendered
through every camera of the scenario's rig and written with its true state, keypoints
(3D and per camera) and their visibility. The same SCENARIO, --seed and options give the
same dataset, so an interrupted render (Ctrl-C) continues with --resume.
"""


def _options(background: str, color: bool, noise: float, blur: float, seed: int,
             appearance: str = "model", skin_tone: str | None = None, shadows: bool = False):
    from digiteyes.synth import RenderOptions

    return RenderOptions(color=color, background=background, noise_sigma=noise,
                         blur_sigma=blur, background_seed=seed, appearance=appearance,
                         skin_tone=skin_tone, shadows=shadows, skin_seed=seed)


def _truth_model(model, perturb: float, seed: int) -> tuple[object, dict | None]:
    """The model the images are rendered from and its description for the metadata."""
    if perturb == 0.0:
        return model, None
    from digiteyes.synth import perturb_model

    truth = perturb_model(model, link_length=perturb, rng=seed)
    links = {link.name: {"length_mm": round(link.length, 6), "radius_mm": round(link.radius, 6)}
             for link in truth.links if link.kind != "palm"}
    palm = [link for link in truth.links if link.kind == "palm"]
    for link in palm:
        links[link.name] = {"size_mm": [round(v, 6) for v in link.size]}
    return truth, {"perturb_model": {"model": model.name, "link_length": perturb, "rng": seed},
                   "file": "truth/model.dh", "links": links}


def _check_resume(folder: Path, settings: dict) -> None:
    """Refuse to resume a sequence that was written with other settings."""
    path = folder / "sequence.json"
    if not path.is_file():
        return
    try:
        old = json.loads(path.read_text(encoding="utf-8")).get("scenario", {}).get("render")
    except (OSError, UnicodeDecodeError, json.JSONDecodeError, AttributeError):
        return  # the writer reports unreadable folders itself
    if old is not None and old != settings:
        changed = sorted(k for k in set(old) | set(settings) if old.get(k) != settings.get(k))
        raise DigitEyesError(f"{folder}: cannot resume: it was rendered with other settings "
                             f"({', '.join(f'{k}={old.get(k)!r}' for k in changed)}); use the "
                             "same options, or --force to start again")


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

    scenario = build_scenario(scenario_name, seed=seed, n_frames=frames)
    if hand_scale != 1.0:
        import dataclasses

        scenario = dataclasses.replace(scenario, metadata={**scenario.metadata,
                                                           "hand_scale": hand_scale})
    render_scenario(scenario, Path(output), seed=seed, background=background, color=color,
                    noise=noise, blur=blur, perturb=perturb, video=video, force=force,
                    resume=resume, appearance=appearance, skin_tone=skin_tone,
                    shadows=shadows)


def render_scenario(scenario, folder: Path, *, seed: int = 0, background: str = "black",
                    color: bool = False, noise: float = 0.0, blur: float = 0.0,
                    perturb: float = 0.0, video: bool = False, force: bool = False,
                    resume: bool = False, progress: bool | None = None,
                    appearance: str = "model", skin_tone: str | None = None,
                    shadows: bool = False) -> Path:
    """Render every frame of ``scenario`` through its rig into the sequence ``folder``
    (shared by ``digiteyes render`` and ``digiteyes demo``); returns the folder. A
    scenario with ``metadata["hand_scale"]`` is drawn from its model scaled by it."""
    from tqdm import tqdm

    from digiteyes.io.dataset import FrameTruth, SequenceWriter
    from digiteyes.synth import render_views
    from digiteyes.synth.setups import truth_model as scaled_truth

    options = _options(background, color, noise, blur, seed, appearance, skin_tone, shadows)
    truth_model, truth_info = _truth_model(scaled_truth(scenario), perturb, seed)
    scale = float(scenario.metadata.get("hand_scale", 1.0))
    if scale != 1.0:
        truth_info = {**(truth_info or {}), "hand_scale": scale, "file": "truth/model.dh"}
    settings = {"scenario": scenario.name, "seed": seed, "frames": scenario.n_frames,
                "background": background, "color": color, "noise_sigma": noise,
                "blur_sigma": blur, "perturb": perturb}
    extra = {"appearance": appearance, "skin_tone": skin_tone, "shadows": shadows,
             "hand_scale": scale if scale != 1.0 else None}
    settings |= {k: v for k, v in extra.items() if v not in ("model", None, False)}
    if resume:
        _check_resume(folder, settings)
    metadata = {"name": scenario.name, "description": scenario.description, "seed": seed,
                "planned_frames": scenario.n_frames, "render": settings,
                "truth_model": truth_info, **scenario.metadata}
    total = scenario.n_frames
    with SequenceWriter(folder, scenario.model, scenario.rig, scenario.initial_state,
                        scenario.fps, name=f"{scenario.name}-seed{seed}", scenario=metadata,
                        video=video, overwrite=force, resume=resume) as writer:
        start = writer.n_written
        if start >= total:
            raise DigitEyesError(f"{folder}: already holds {start} frames of {total}; "
                                 "nothing to render")
        bar = tqdm(total=total, initial=start, unit="frame", desc=f"render {scenario.name}",
                   disable=None if progress is None else not progress)
        try:
            for t in range(start, total):
                views = render_views(truth_model, scenario.states[t], scenario.rig, options,
                                     np.random.default_rng([seed, t]))
                writer.write_frame([v.image for v in views], FrameTruth(
                    scenario.states[t], views[0].keypoint_names, views[0].keypoints_3d,
                    np.stack([v.keypoints_2d for v in views]),
                    np.stack([v.visible for v in views])))
                bar.update()
        except KeyboardInterrupt:
            bar.close()
            click.echo(f"digiteyes render: stopped after {writer.n_written} of {total} frames; "
                       f"run the same command with --resume to continue", err=True)
            raise
        bar.close()
    if truth_info is not None:
        from digiteyes.kinematics import format_model_text

        (folder / "truth").mkdir(exist_ok=True)
        (folder / "truth" / "model.dh").write_text(format_model_text(truth_model.spec),
                                                  encoding="utf-8")
    click.echo(f"wrote {total - start} frame(s) x {len(scenario.rig)} camera(s) of "
               f"{scenario.name} (seed {seed}) to {folder}")
    return folder
