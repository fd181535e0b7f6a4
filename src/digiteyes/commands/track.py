"""``digiteyes track``: run the DigitEyes feature tracker on a dataset folder or videos."""

from __future__ import annotations

import click

from digiteyes.pipeline import TrackingRun
from digiteyes.track_job import TrackJob, run_track_job, tracker_options

__all__ = ["print_run", "track", "tracker_options"]

HELP = """Track INPUT with the DigitEyes feature tracker (thesis Sec. 4.3).

INPUT is a dataset folder (see docs/dataset.md; its model, rig and initial state are used
unless overridden) or one video file per camera of the rig, in rig order (then --model,
--rig and --init are required). Writes states.csv, overlay.mp4, views/, trajectory plots
and summary.json into OUT. Ctrl-C keeps every frame tracked so far.
"""


def print_run(run: TrackingRun) -> None:
    """Headline figures of a run and where its files are."""
    click.echo(f"tracked {run.n_frames} frame(s) in {run.tracker_seconds:.2f} s of tracker "
               f"time ({run.tracker_fps:.1f} frames/s, {run.ms_per_iteration:.2f} ms per "
               f"Gauss-Newton iteration)")
    if run.n_lost:
        click.echo(f"track flagged lost in {run.n_lost} frame(s), first at frame "
                   f"{run.first_lost_frame}")
    for key in ("states", "overlay", "trajectory-palm", "trajectory-joints", "summary"):
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
@click.option("--quiet", is_flag=True, help="No progress bar.")
def track(inputs: tuple[str, ...], model_name: str | None, rig_path: str | None,
          init_path: str | None, output: str, iterations: int, window: float, links: str,
          robust: str | None, prediction: str, shading: bool, max_frames: int | None,
          fps: float | None, no_overlay: bool, quiet: bool) -> None:
    job = TrackJob(inputs, output, model_name, rig_path, init_path, iterations, window, links,
                   robust, prediction, shading, max_frames, fps, not no_overlay, not quiet)
    run = run_track_job(job)
    print_run(run)
    if run.interrupted:
        raise KeyboardInterrupt
