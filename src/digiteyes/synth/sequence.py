"""Render a scenario frame by frame, with its truth: in memory (:func:`render_frames`) or
into a sequence folder on disk (:func:`render_scenario`, behind ``digiteyes render`` and
``digiteyes demo``; the tracker benchmark keeps the frames in memory).

Frame ``t`` draws its sensor noise from ``numpy.random.default_rng([seed, t])``, so the
same scenario, seed and options give the same images, in memory or on disk, and an
interrupted render continues where it stopped.
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from tqdm import tqdm

from digiteyes.camera import Rig
from digiteyes.errors import DigitEyesError
from digiteyes.io.dataset import FrameTruth, SequenceWriter
from digiteyes.jsonfile import read_json_object
from digiteyes.kinematics import KinematicModel, format_model_text
from digiteyes.synth.options import RenderOptions
from digiteyes.synth.perturb import perturb_model
from digiteyes.synth.scenarios import Scenario
from digiteyes.synth.setups import truth_model as scaled_truth_model
from digiteyes.synth.views import render_views


def render_frames(scenario: Scenario, options: RenderOptions, *, seed: int = 0,
                  truth_model: KinematicModel | None = None, rig: Rig | None = None,
                  start: int = 0, progress: bool | None = False, label: str = ""
                  ) -> Iterator[tuple[list[np.ndarray], FrameTruth]]:
    """Yield ``(images, truth)`` for frames ``start..`` of ``scenario``: one image per
    camera of ``rig`` (default: the scenario's) drawn from ``truth_model`` (default: the
    scenario's model) with ``options``; noise seeded by ``[seed, t]``."""
    model = truth_model or scenario.model
    rig = rig or scenario.rig
    for t in tqdm(range(start, scenario.n_frames), initial=start, total=scenario.n_frames,
                  unit="frame", desc=label or f"render {scenario.name}", leave=False,
                  disable=None if progress is None else not progress):
        views = render_views(model, scenario.states[t], rig, options,
                             np.random.default_rng([seed, t]))
        yield [v.image for v in views], FrameTruth(
            scenario.states[t], tuple(views[0].keypoint_names), views[0].keypoints_3d,
            np.stack([v.keypoints_2d for v in views]), np.stack([v.visible for v in views]))


def perturbed_truth(model: KinematicModel, perturb: float, seed: int
                    ) -> tuple[KinematicModel, dict[str, Any] | None]:
    """The model the images are drawn from (``model`` itself when ``perturb`` is 0, else
    :func:`~digiteyes.synth.perturb.perturb_model` with link lengths off by up to that
    fraction) and its description for the sequence metadata (None when unperturbed)."""
    if perturb == 0.0:
        return model, None
    truth = perturb_model(model, link_length=perturb, rng=seed)
    links: dict[str, Any] = {
        link.name: {"length_mm": round(link.length, 6), "radius_mm": round(link.radius, 6)}
        for link in truth.links if link.kind != "palm"}
    for link in truth.links:
        if link.kind == "palm":
            links[link.name] = {"size_mm": [round(v, 6) for v in link.size]}
    return truth, {"perturb_model": {"model": model.name, "link_length": perturb, "rng": seed},
                   "file": "truth/model.dh", "links": links}


@dataclass(frozen=True)
class RenderedScenario:
    """What :func:`render_scenario` wrote: the folder and the frames written this time."""

    folder: Path
    first_frame: int
    n_written: int


def _check_resume(folder: Path, settings: dict) -> None:
    """Refuse to resume a sequence that was written with other settings."""
    path = folder / "sequence.json"
    if not path.is_file():
        return
    try:
        old = read_json_object(path, DigitEyesError, "file").get("scenario", {}).get("render")
    except (DigitEyesError, AttributeError):
        return  # the writer reports unreadable folders itself
    if old is not None and old != settings:
        changed = sorted(k for k in set(old) | set(settings) if old.get(k) != settings.get(k))
        raise DigitEyesError(f"{folder}: cannot resume: it was rendered with other settings "
                             f"({', '.join(f'{k}={old.get(k)!r}' for k in changed)}); use the "
                             "same options, or --force to start again")


def render_scenario(scenario: Scenario, folder: str | Path, *, seed: int = 0,
                    background: str = "black", color: bool = False, noise: float = 0.0,
                    blur: float = 0.0, perturb: float = 0.0, video: bool = False,
                    force: bool = False, resume: bool = False,
                    progress: bool | None = None, appearance: str = "model",
                    skin_tone: str | None = None, shadows: bool = False
                    ) -> RenderedScenario:
    """Render every frame of ``scenario`` through its rig into the sequence ``folder``
    (docs/dataset.md), with its truth; ``resume`` continues an interrupted render made
    with the same settings, ``force`` lets the writer replace the folder. A Ctrl-C leaves
    the frames written so far (the folder can be resumed). ``appearance`` is ``"model"``
    or ``"flesh"`` (docs/appearance.md); a scenario with ``metadata["hand_scale"]`` is
    drawn from its model scaled by it (the tracking model in the folder stays as it is)."""
    folder = Path(folder)
    options = RenderOptions(color=color, background=background, noise_sigma=noise,
                            blur_sigma=blur, background_seed=seed, appearance=appearance,
                            skin_tone=skin_tone, shadows=shadows, skin_seed=seed)
    truth_model, truth_info = perturbed_truth(scaled_truth_model(scenario), perturb, seed)
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
        for images, truth in render_frames(scenario, options, seed=seed,
                                           truth_model=truth_model, start=start,
                                           progress=progress):
            writer.write_frame(images, truth)
    if truth_info is not None:
        (folder / "truth").mkdir(exist_ok=True)
        (folder / "truth" / "model.dh").write_text(format_model_text(truth_model.spec),
                                                  encoding="utf-8")
    return RenderedScenario(folder, start, total - start)
