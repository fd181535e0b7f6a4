"""``digiteyes track``: the command line over :func:`digiteyes.track_job.run_track_job`
(a registered tracker, default the DigitEyes feature tracker, on a dataset folder, videos
or a live camera)."""

from __future__ import annotations

import json
from dataclasses import replace

import click

from digiteyes.camera.default import DEFAULT_HFOV_DEG
from digiteyes.camera.mirror import HANDS
from digiteyes.camera.working_size import DEFAULT_MAX_SIDE
from digiteyes.detect.pose import DETECTORS
from digiteyes.filters import OneEuroOptions
from digiteyes.io.frame_sinks import parse_stream_target
from digiteyes.pipeline import TrackingRun
from digiteyes.track_job import (
    AUTO_HAND,
    AUTO_TRACKER,
    DEFAULT_CHECK_EVERY,
    TrackJob,
    run_track_job,
    tracker_options,
)
from digiteyes.trackers import DEFAULT_TRACKER, tracker_entry, tracker_names
from digiteyes.warmup import COMPILE_MESSAGE, DEMO_KERNELS, cold_kernels

__all__ = ["parse_tracker_options", "print_run", "smoothing_options", "track",
           "tracker_options"]

HELP = """Track INPUT with a registered tracker (--tracker; default auto: the keypoint
tracker on footage when MediaPipe is installed, else the DigitEyes feature tracker,
thesis Sec. 4.3; docs/keypoint-tracker.md).

INPUT is a dataset folder (see docs/dataset.md; its model, rig and initial state are used
unless overridden), one video file per camera of the rig, in rig order, one folder of
numbered images per camera (frames at --fps), or nothing with --camera N (a live camera).
Videos, images and cameras use --model (default: hand), --rig (default:
one camera of --hfov field of view) and --init FILE or --init auto (the default for them:
detect the hand and fit the model; lost frames are then re-detected). Writes states.csv,
keypoints.csv, joint_angles.csv, overlay.mp4, views/, trajectory plots, summary.json and
report.html into OUT. Ctrl-C keeps every frame tracked so far.
"""


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
    return ("Tracker to run: auto (keypoints for videos and cameras, and for datasets "
            "whose hand MediaPipe finds at their start, when the MediaPipe extra is "
            f"installed; else {DEFAULT_TRACKER}); " + "; ".join(
                f"{name} ({tracker_entry(name).help})" for name in tracker_names()) + ".")


class TrackerChoice(click.Choice):
    """The registered tracker names, read when the command line is parsed (so a tracker
    registered after this module was imported is a choice too)."""

    def __init__(self) -> None:
        super().__init__(())

    @property
    def choices(self) -> tuple[str, ...]:
        return (AUTO_TRACKER, *tracker_names())

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
    unless ``--smooth`` or a setting is given; ``beta`` sets ``beta_per_mm_s``."""
    if not (smooth or min_cutoff is not None or beta is not None):
        return None
    defaults = OneEuroOptions()
    changes: dict[str, float] = {}
    if min_cutoff is not None:
        changes["min_cutoff_hz"] = min_cutoff
    if beta is not None:
        changes["beta_per_mm_s"] = beta
    return replace(defaults, **changes)


def print_run(run: TrackingRun, err: bool = False) -> None:
    """Headline figures of a run and where its files are (on standard error with
    ``err``)."""

    def echo(line: str) -> None:
        click.echo(line, err=err)

    per_iteration = (f", {run.ms_per_iteration:.2f} ms per iteration"
                     if run.iterations else "")
    echo(f"tracked {run.n_frames} frame(s) with {run.tracker} in "
         f"{run.tracker_seconds:.2f} s of tracker time ({run.tracker_fps:.1f} frames/s"
         f"{per_iteration})")
    if run.warm_up_seconds >= 1.0:
        echo(f"  (kernels compiled or loaded in a first, untimed step: "
             f"{run.warm_up_seconds:.1f} s, not counted above)")
    if run.n_lost:
        echo(f"track flagged lost in {run.n_lost} frame(s), first at frame "
             f"{run.first_lost_frame}")
    if run.reinitialised_frames:
        echo(f"re-initialised from a detection in {len(run.reinitialised_frames)} frame(s)")
    for key in ("states", "keypoints", "states-smoothed", "joint-angles", "overlay",
                "trajectory-palm", "trajectory-joints", "summary", "report"):
        if key in run.files:
            echo(f"  {key:<18} {run.files[key]}")
    views = sorted(k for k in run.files if k.startswith("view-"))
    if views:
        echo(f"  {'3D views':<18} {run.files[views[0]].parent}/ ({len(views)} PNGs)")


@click.command(help=HELP)
@click.argument("inputs", nargs=-1, required=False, metavar="[INPUT...]")
@click.option("--model", "model_name",
              help="Model name or .dh file (default: the dataset's, else hand).")
@click.option("--rig", "rig_path", type=click.Path(dir_okay=False),
              help="Rig file (JSON or OpenCV YAML; default: the dataset's, else a default "
                   "camera of --hfov).")
@click.option("--init", "init_path", metavar="FILE|auto",
              help="Initial state JSON, or 'auto' to detect the hand and fit the model "
                   "(default: the dataset's; auto for videos, images and cameras).")
@click.option("-o", "--output", required=True, type=click.Path(file_okay=False),
              help="Output folder.")
@click.option("--camera", type=click.IntRange(min=0), default=None,
              help="Track live camera N (OpenCV index) instead of files.")
@click.option("--show", is_flag=True, help="Show the overlay in a window while tracking.")
@click.option("--stream", metavar="-|tcp://HOST:PORT", default=None,
              help="Send each frame's state and keypoints as a JSON line to standard "
                   "output (-) or a listening TCP socket.")
@click.option("--detector", type=click.Choice(DETECTORS),
              default="auto", show_default=True,
              help="Detector of --init auto and of the recovery after loss (auto = MediaPipe "
                   "when installed, the classic detector where it finds no hand).")
@click.option("--hand", type=click.Choice((AUTO_HAND, *HANDS)), default=AUTO_HAND,
              show_default=True,
              help="The hand in the images; a left hand is tracked as the right hand of the "
                   "mirror image (outputs in the real images); auto: the side the detector "
                   "reports at --init auto (right with a given start).")
@click.option("--max-size", "max_side", type=click.IntRange(min=64),
              default=DEFAULT_MAX_SIDE, show_default=True,
              help="Track images whose longer side exceeds this many pixels resized to it "
                   "(outputs stay in the images' pixels).")
@click.option("--check-every", type=click.IntRange(min=0), default=DEFAULT_CHECK_EVERY,
              show_default=True,
              help="On footage with MediaPipe: check the track against its keypoints every "
                   "N frames and treat a track off the hand as lost (0: never; not for "
                   "the keypoints tracker, which follows them anyway).")
@click.option("--init-frames", type=click.IntRange(min=1), default=None,
              help="Frames --init auto may search for the hand (default: until it shows).")
@click.option("--recover/--no-recover", default=None,
              help="Re-detect and re-fit after a lost frame (default: with --init auto).")
@click.option("--hfov", type=click.FloatRange(min=1, max=179, min_open=True, max_open=True),
              default=DEFAULT_HFOV_DEG, show_default=True,
              help="Horizontal field of view (deg) of the default camera (no --rig).")
@click.option("--tracker", "tracker_name", cls=TrackerOption, type=TrackerChoice(),
              default=AUTO_TRACKER, show_default=True)
@click.option("--option", "option_pairs", multiple=True, metavar="KEY=VALUE",
              help="A field of the tracker's options (repeatable), e.g. "
                   "--option iterations_per_frame=3; a dotted key sets a field of nested "
                   "settings (--option digit_search.passes=0); for the features tracker "
                   "on top of the flags below.")
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
              help="Frame rate of the input: overlay video, smoothing, summary (default: the "
                   "dataset's or the video's, else 10).")
@click.option("--no-overlay", is_flag=True, help="Skip the overlay video.")
@click.option("--smooth", is_flag=True,
              help="Also write states-smoothed.csv and joint_angles-smoothed.csv, One Euro "
                   "filtered (docs/output.md).")
@click.option("--min-cutoff", type=click.FloatRange(min=0, min_open=True), default=None,
              help="One Euro min_cutoff_hz (implies --smooth; default "
                   f"{OneEuroOptions().min_cutoff_hz:g}).")
@click.option("--beta", type=click.FloatRange(min=0), default=None,
              help="One Euro beta_per_mm_s, Hz per mm/s of keypoint speed (implies "
                   f"--smooth; default {OneEuroOptions().beta_per_mm_s:g}).")
@click.option("--quiet", is_flag=True, help="No progress bar.")
@click.option("--strict", is_flag=True,
              help="Refuse videos of different lengths instead of tracking the shortest.")
def track(inputs: tuple[str, ...], model_name: str | None, rig_path: str | None,
          init_path: str | None, output: str, camera: int | None, show: bool,
          stream: str | None, detector: str, hand: str, max_side: int, check_every: int,
          init_frames: int | None,
          recover: bool | None, hfov: float,
          tracker_name: str, option_pairs: tuple[str, ...], iterations: int, window: float,
          links: str, robust: str | None, prediction: str, shading: bool,
          max_frames: int | None, fps: float | None, no_overlay: bool, smooth: bool,
          min_cutoff: float | None, beta: float | None, quiet: bool,
          strict: bool = False) -> None:
    if stream is not None:
        parse_stream_target(stream)
    # with --stream - the JSON lines own standard output; messages go to standard error
    err = stream == "-"
    job = TrackJob(
        inputs, output, model_name, rig_path, init_path, iterations, window, links, robust,
        prediction, shading, max_frames, fps, overlay=not no_overlay, progress=not quiet,
        tracker_name=tracker_name, options=tuple(parse_tracker_options(option_pairs).items()),
        strict=strict, smooth=smoothing_options(smooth, min_cutoff, beta), camera=camera,
        show=show, stream=stream, detector=detector, hfov=hfov, recover=recover,
        init_frames=init_frames, hand=hand, max_side=max_side, check_every=check_every)
    # the default tracker compiles the demo's kernels (its silhouette check draws with the
    # renderer's); other trackers may compile any
    if cold_kernels(only=DEMO_KERNELS if tracker_name in (DEFAULT_TRACKER, AUTO_TRACKER)
                    else None):
        click.echo(COMPILE_MESSAGE, err=err)
    run = run_track_job(job, echo=lambda line: click.echo(line, err=err))
    print_run(run, err=err)
    if run.interrupted:
        raise KeyboardInterrupt
