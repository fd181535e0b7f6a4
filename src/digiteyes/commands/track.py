"""``digiteyes track``: run a registered tracker (default: the DigitEyes feature tracker)
on a dataset folder or videos."""

from __future__ import annotations

import json
from dataclasses import replace
from itertools import chain, islice
from pathlib import Path

import click
import numpy as np

from digiteyes.camera import load_rig
from digiteyes.commands._video_lengths import check_lengths, record_missing
from digiteyes.errors import CameraError, DatasetError
from digiteyes.evaluate.report_page import write_report_page
from digiteyes.features import FeatureOptions
from digiteyes.filters import OneEuroOptions
from digiteyes.io import open_sequence, open_video_frames
from digiteyes.io.track_extras import write_track_extras
from digiteyes.kinematics import State, load_model
from digiteyes.pipeline import TrackingRun, run_tracker
from digiteyes.trackers import (
    DEFAULT_TRACKER,
    FeatureTrackerOptions,
    all_features,
    create_tracker,
    thesis_whole_hand_links,
    tracker_entry,
    tracker_names,
)
from digiteyes.warmup import COMPILE_MESSAGE, cold_kernels

HELP = """Track INPUT with a registered tracker (--tracker; default: the DigitEyes feature
tracker, thesis Sec. 4.3).

INPUT is a dataset folder (see docs/dataset.md; its model, rig and initial state are used
unless overridden) or one video file per camera of the rig, in rig order (then --model,
--rig and --init are required). Writes states.csv, joint_angles.csv, overlay.mp4, views/,
trajectory plots, summary.json and report.html into OUT. Ctrl-C keeps every frame tracked so far.
"""


def tracker_options(iterations: int, window: float, links: str, model, robust: str | None,
                    prediction: str, shading: bool = True) -> FeatureTrackerOptions:
    """Tracker settings from the command-line choices (shared with ``digiteyes demo``)."""
    chosen = {"default": None, "all": all_features(model),
              "thesis": thesis_whole_hand_links(model)}[links]
    return FeatureTrackerOptions(
        iterations_per_frame=iterations,
        features=FeatureOptions(window_px=window),
        links=chosen,
        robust_loss=robust,
        prediction=prediction,
        shading_correction=shading,
    )


def parse_tracker_options(pairs: tuple[str, ...]) -> dict[str, object]:
    """``KEY=VALUE`` pairs as options; a VALUE that reads as JSON (numbers, true, null,
    lists) is taken as such, any other as a string."""
    options: dict[str, object] = {}
    for pair in pairs:
        key, eq, value = pair.partition("=")
        if not eq or not key:
            raise click.BadParameter(f"expected KEY=VALUE, got {pair!r}",
                                     param_hint="'--option'")
        try:
            options[key] = json.loads(value)
        except json.JSONDecodeError:
            options[key] = value
    return options


def tracker_help() -> str:
    """The ``--tracker`` help: every registered name with its one line."""
    return "Tracker to run: " + "; ".join(
        f"{name} ({tracker_entry(name).help})" for name in tracker_names()) + "."


class TrackerChoice(click.Choice):
    """The registered tracker names, read when the command line is parsed (so a tracker
    registered after this module was imported is a choice too)."""

    def __init__(self) -> None:
        super().__init__(())

    @property
    def choices(self) -> tuple[str, ...]:
        return tracker_names()

    @choices.setter
    def choices(self, value) -> None:
        """The registry decides; :class:`click.Choice` sets this in its constructor."""


class TrackerOption(click.Option):
    """``--tracker``, whose help lists the trackers registered when it is shown."""

    def get_help_record(self, ctx: click.Context) -> tuple[str, str] | None:
        self.help = tracker_help()
        return super().get_help_record(ctx)


def smoothing_options(smooth: bool, min_cutoff: float | None,
                      beta: float | None) -> OneEuroOptions | None:
    """One Euro settings from the command line (shared with ``digiteyes export``): None
    unless ``--smooth`` or a setting is given; ``beta`` sets ``beta_per_rad`` and, in the
    defaults' proportion, ``beta_per_mm``."""
    if not (smooth or min_cutoff is not None or beta is not None):
        return None
    defaults = OneEuroOptions()
    changes: dict[str, float] = {}
    if min_cutoff is not None:
        changes["min_cutoff_hz"] = min_cutoff
    if beta is not None:
        changes["beta_per_rad"] = beta
        changes["beta_per_mm"] = beta * defaults.beta_per_mm / defaults.beta_per_rad
    return replace(defaults, **changes)


def print_run(run: TrackingRun) -> None:
    """Headline figures of a run and where its files are."""
    per_iteration = (f", {run.ms_per_iteration:.2f} ms per iteration"
                     if run.iterations else "")
    click.echo(f"tracked {run.n_frames} frame(s) with {run.tracker} in "
               f"{run.tracker_seconds:.2f} s of tracker time ({run.tracker_fps:.1f} frames/s"
               f"{per_iteration})")
    if run.warm_up_seconds >= 1.0:
        click.echo(f"  (kernels compiled or loaded in a first, untimed step: "
                   f"{run.warm_up_seconds:.1f} s, not counted above)")
    if run.n_lost:
        click.echo(f"track flagged lost in {run.n_lost} frame(s), first at frame "
                   f"{run.first_lost_frame}")
    for key in ("states", "states-smoothed", "joint-angles", "overlay", "trajectory-palm",
                "trajectory-joints", "summary", "report"):
        if key in run.files:
            click.echo(f"  {key:<18} {run.files[key]}")
    views = sorted(k for k in run.files if k.startswith("view-"))
    if views:
        click.echo(f"  {'3D views':<18} {run.files[views[0]].parent}/ ({len(views)} PNGs)")


@click.command(help=HELP)
@click.argument("inputs", nargs=-1, required=True, metavar="INPUT...")
@click.option("--model", "model_name", help="Model name or .dh file (default: the dataset's).")
@click.option("--rig", "rig_path", type=click.Path(dir_okay=False),
              help="Rig file (JSON or OpenCV YAML; default: the dataset's).")
@click.option("--init", "init_path", type=click.Path(dir_okay=False),
              help="Initial state JSON (default: the dataset's).")
@click.option("-o", "--output", required=True, type=click.Path(file_okay=False),
              help="Output folder.")
@click.option("--tracker", "tracker_name", cls=TrackerOption, type=TrackerChoice(),
              default=DEFAULT_TRACKER, show_default=True)
@click.option("--option", "option_pairs", multiple=True, metavar="KEY=VALUE",
              help="A field of the tracker's options (repeatable), e.g. "
                   "--option iterations_per_frame=3; for the features tracker on top of "
                   "the flags below.")
@click.option("--iterations", type=click.IntRange(min=1), default=5, show_default=True,
              help="Gauss-Newton iterations per frame (features tracker).")
@click.option("--window", type=click.FloatRange(min=2.0), default=20.0, show_default=True,
              help="Feature search window, pixels (thesis Table 4.2).")
@click.option("--links", type=click.Choice(["default", "all", "thesis"]), default="default",
              show_default=True,
              help="Features to measure: default (all but the hand's interpenetrating middle "
                   "and ring proximal links), all, or the thesis's set (Sec. 4.3.3, no palm "
                   "edges).")
@click.option("--robust", type=click.Choice(["huber", "tukey"]), default=None,
              help="Robust loss on the feature residuals.")
@click.option("--prediction", type=click.Choice(["none", "constant-velocity"]),
              default="none", show_default=True,
              help="Start each frame from the previous estimate (thesis) or extrapolate.")
@click.option("--shading/--no-shading", default=True, show_default=True,
              help="Correct the edges for skin shading, predicted from a light fitted on the "
                   "first frame (docs/features.md); off is about 4 ms per frame and camera "
                   "faster.")
@click.option("--frames", "max_frames", type=click.IntRange(min=1), default=None,
              help="Track at most this many frames.")
@click.option("--fps", type=click.FloatRange(min=0.1), default=None,
              help="Frame rate of the overlay video (default: the dataset's, or 10).")
@click.option("--no-overlay", is_flag=True, help="Skip the overlay video.")
@click.option("--smooth", is_flag=True,
              help="Also write states-smoothed.csv and joint_angles-smoothed.csv, One Euro "
                   "filtered (docs/output.md).")
@click.option("--min-cutoff", type=click.FloatRange(min=0, min_open=True), default=None,
              help="One Euro min_cutoff_hz (implies --smooth; default 0.1).")
@click.option("--beta", type=click.FloatRange(min=0), default=None,
              help="One Euro beta_per_rad (implies --smooth; default 5).")
@click.option("--quiet", is_flag=True, help="No progress bar.")
@click.option("--strict", is_flag=True,
              help="Refuse videos of different lengths instead of tracking the shortest.")
def track(inputs: tuple[str, ...], model_name: str | None, rig_path: str | None,
          init_path: str | None, output: str, tracker_name: str,
          option_pairs: tuple[str, ...], iterations: int, window: float, links: str,
          robust: str | None, prediction: str, shading: bool, max_frames: int | None,
          fps: float | None, no_overlay: bool, smooth: bool, min_cutoff: float | None,
          beta: float | None, quiet: bool, strict: bool = False) -> None:
    dataset = None
    lengths = None
    if len(inputs) == 1 and Path(inputs[0]).is_dir():
        dataset = open_sequence(inputs[0])
    elif any(Path(p).is_dir() for p in inputs):
        raise DatasetError("give one dataset folder, or one video file per camera")
    if dataset is None and not (model_name and rig_path and init_path):
        raise click.UsageError("tracking videos needs --model, --rig and --init")
    model = load_model(model_name) if model_name else dataset.model
    rig = load_rig(rig_path) if rig_path else dataset.rig
    if init_path:
        initial = State.load_json(model, init_path).q
    else:
        initial = State(model, dataset.initial_state).q
    if dataset is not None:
        frames = iter(dataset)
        total = dataset.n_frames
        rate = fps or dataset.fps
    else:
        if len(inputs) != len(rig):
            raise CameraError(f"the rig has {len(rig)} camera(s) ({', '.join(rig.names)}) but "
                              f"{len(inputs)} video(s) were given")
        lengths = check_lengths(list(inputs), strict)
        frames = open_video_frames(list(inputs))
        total = None
        rate = fps or 10.0
    if max_frames is not None:
        frames = islice(frames, max_frames)
        total = max_frames if total is None else min(total, max_frames)
    first = next(frames, None)
    if first is None:
        raise DatasetError(f"{inputs[0]}: no frames to track")
    options = parse_tracker_options(option_pairs)
    if tracker_name == DEFAULT_TRACKER:
        flags = tracker_options(iterations, window, links, model, robust, prediction, shading)
        options = {**vars(flags), **options}
    tracker = create_tracker(tracker_name, model, rig, **options)
    if cold_kernels():
        click.echo(COMPILE_MESSAGE)
    run = run_tracker(tracker, model, rig, chain([first], frames), np.asarray(initial),
                      output, fps=rate, total=total, overlay=not no_overlay,
                      progress=not quiet, tracker_name=tracker_name)
    if lengths is not None and not run.interrupted and max_frames is None:
        record_missing(run.files["summary"], lengths[0], run.n_frames, lengths[1])
    run.files.update(write_track_extras(output, model, rate,
                                        smoothing_options(smooth, min_cutoff, beta)))
    run.files["report"] = write_report_page(output)
    print_run(run)
    if run.interrupted:
        raise KeyboardInterrupt
