"""``digiteyes track``: run the DigitEyes feature tracker on a dataset folder or videos."""

from __future__ import annotations

from dataclasses import replace
from itertools import chain, islice
from pathlib import Path

import click
import numpy as np

from digiteyes.camera import load_rig
from digiteyes.errors import CameraError, DatasetError
from digiteyes.features import FeatureOptions
from digiteyes.filters import OneEuroOptions
from digiteyes.io import open_sequence, open_video_frames
from digiteyes.io.track_extras import write_track_extras
from digiteyes.kinematics import State
from digiteyes.models import load_model
from digiteyes.pipeline import TrackingRun, run_tracker
from digiteyes.trackers import (
    FeatureTracker,
    FeatureTrackerOptions,
    all_features,
    thesis_whole_hand_links,
)
from digiteyes.viz.report_page import write_report_page

HELP = """Track INPUT with the DigitEyes feature tracker (thesis Sec. 4.3).

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
    click.echo(f"tracked {run.n_frames} frame(s) in {run.tracker_seconds:.2f} s of tracker "
               f"time ({run.tracker_fps:.1f} frames/s, {run.ms_per_iteration:.2f} ms per "
               f"Gauss-Newton iteration)")
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
@click.option("--iterations", type=click.IntRange(min=1), default=5, show_default=True,
              help="Gauss-Newton iterations per frame.")
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
def track(inputs: tuple[str, ...], model_name: str | None, rig_path: str | None,
          init_path: str | None, output: str, iterations: int, window: float, links: str,
          robust: str | None, prediction: str, shading: bool, max_frames: int | None,
          fps: float | None, no_overlay: bool, smooth: bool, min_cutoff: float | None,
          beta: float | None, quiet: bool) -> None:
    dataset = None
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
        frames = open_video_frames(list(inputs))
        total = None
        rate = fps or 10.0
    if max_frames is not None:
        frames = islice(frames, max_frames)
        total = max_frames if total is None else min(total, max_frames)
    first = next(frames, None)
    if first is None:
        raise DatasetError(f"{inputs[0]}: no frames to track")
    rig.check_images(first)
    options = tracker_options(iterations, window, links, model, robust, prediction, shading)
    tracker = FeatureTracker(model, rig, options)
    run = run_tracker(tracker, model, rig, chain([first], frames), np.asarray(initial),
                      output, fps=rate, total=total, overlay=not no_overlay,
                      progress=not quiet)
    run.files.update(write_track_extras(output, model, rate,
                                        smoothing_options(smooth, min_cutoff, beta)))
    run.files["report"] = write_report_page(output)
    print_run(run)
    if run.interrupted:
        raise KeyboardInterrupt
