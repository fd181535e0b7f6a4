"""``digiteyes export TRACK_DIR -o OUT_DIR --format bvh|gltf|csv|parquet``."""

from __future__ import annotations

from pathlib import Path

import click

HELP = """Export the track in TRACK_DIR (a `digiteyes track` output folder, or its
states.csv) for animation and analysis tools (docs/output.md): BVH (track.bvh, mm), glTF
2.0 (track.glb, an animated skinned skeleton, metres), CSV or Parquet (track.csv,
track.parquet: states, joint angles in degrees, 3D keypoints in mm). --smooth applies the
One Euro filter first. A track whose tracker fitted the hand's size (states.csv's
hand_scale column) is exported with the model at the track's median size."""


@click.command(help=HELP)
@click.argument("track_dir", metavar="TRACK_DIR", type=click.Path(exists=True, path_type=Path))
@click.option("-o", "--output", required=True, type=click.Path(file_okay=False, path_type=Path),
              help="Output folder.")
@click.option("--format", "formats", multiple=True, required=True,
              type=click.Choice(["bvh", "gltf", "csv", "parquet"]),
              help="Export format (repeat for several).")
@click.option("--model", "model_name",
              help="Model name or .dh file (default: the shipped model the log's header fits).")
@click.option("--fps", type=click.FloatRange(min=0.1), default=None,
              help="Frame rate (default: TRACK_DIR/summary.json's, else 10).")
@click.option("--smooth", is_flag=True, help="One Euro filter the states first (defaults).")
@click.option("--min-cutoff", type=click.FloatRange(min=0, min_open=True), default=None,
              help="One Euro min_cutoff_hz (implies --smooth).")
@click.option("--beta", type=click.FloatRange(min=0), default=None,
              help="One Euro beta_per_mm_s, Hz per mm/s (implies --smooth).")
def export(track_dir: Path, output: Path, formats: tuple[str, ...], model_name: str | None,
           fps: float | None, smooth: bool, min_cutoff: float | None,
           beta: float | None) -> None:
    from digiteyes.commands.track import smoothing_options
    from digiteyes.io.export import export_track
    from digiteyes.io.track_extras import read_track, track_is_left_hand
    from digiteyes.kinematics import load_model
    from digiteyes.kinematics.scaling import model_of_size

    options = smoothing_options(smooth, min_cutoff, beta)
    model = load_model(model_name) if model_name else None
    model, log, fps = read_track(track_dir, model, fps, options)
    left = track_is_left_hand(track_dir if track_dir.is_dir() else track_dir.parent)
    size = log.median_hand_scale
    model = model_of_size(model, size)  # the states pose a hand of this size
    for fmt in dict.fromkeys(formats):
        path = export_track(model, log.frames, log.states, log.lost, fps, output, fmt, left)
        click.echo(f"wrote {path} ({len(log)} frames, {fps:g} frames/s"
                   f"{', One Euro filtered' if options else ''}"
                   f"{f', the hand {size:.3f} times the model' if size != 1.0 else ''}"
                   f"{', a left hand (the mirror image reflected back)' if left else ''})")
