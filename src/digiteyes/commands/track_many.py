"""``digiteyes track-many``: track many videos or dataset folders, one Ray task each."""

from __future__ import annotations

import click

from digiteyes.errors import DigitEyesError
from digiteyes.track_job import TrackJob
from digiteyes.track_many import SUMMARY_FILE, track_many

HELP = """Track every INPUT (a dataset folder, or a one-camera video) as one Ray task.

Each input's outputs (as `digiteyes track` writes them) go to OUT/<input name>/, and a
DONE.json written last marks it finished: a rerun skips finished inputs and retries the
others. A failing input is reported and the others go on. Ray runs locally with --workers
CPUs, or on the cluster at --address. Needs Ray: pip install 'digiteyes[cluster]'.
"""


@click.command("track-many", help=HELP)
@click.argument("inputs", nargs=-1, required=True, metavar="INPUT...")
@click.option("-o", "--output", required=True, type=click.Path(file_okay=False),
              help="Output root folder.")
@click.option("--workers", type=click.IntRange(min=1), default=None,
              help="CPUs of the local Ray (default: all cores).")
@click.option("--address", default=None,
              help="Ray cluster to run on (e.g. auto or ray://HEAD:10001).")
@click.option("--model", "model_name", help="Model for videos (datasets bring their own).")
@click.option("--rig", "rig_path", type=click.Path(dir_okay=False), help="Rig for videos.")
@click.option("--init", "init_path", type=click.Path(dir_okay=False),
              help="Initial state JSON for videos, or auto (detect and fit).")
@click.option("--iterations", type=click.IntRange(min=1), default=5, show_default=True,
              help="Gauss-Newton iterations per frame.")
@click.option("--shading/--no-shading", default=True, show_default=True,
              help="Shading correction (as digiteyes track).")
@click.option("--frames", "max_frames", type=click.IntRange(min=1), default=None,
              help="Track at most this many frames of each input.")
@click.option("--no-overlay", is_flag=True, help="Skip the overlay videos.")
@click.option("--quiet", is_flag=True, help="No progress bars.")
def track_many_command(inputs: tuple[str, ...], output: str, workers: int | None,
                       address: str | None, model_name: str | None, rig_path: str | None,
                       init_path: str | None, iterations: int, shading: bool,
                       max_frames: int | None, no_overlay: bool, quiet: bool) -> None:
    template = TrackJob((), output, model_name, rig_path, init_path, iterations,
                        shading=shading, max_frames=max_frames, overlay=not no_overlay)
    summary = track_many(list(inputs), output, template, workers=workers, address=address,
                         progress=not quiet, echo=click.echo)
    counts = {s: sum(r.status == s for r in summary.results)
              for s in ("done", "skipped", "failed")}
    click.echo(f"{counts['done']} done, {counts['skipped']} skipped (done before), "
               f"{counts['failed']} failed in {summary.wall_seconds:.1f} s; summary in "
               f"{output}/{SUMMARY_FILE}")
    for result in summary.failed:
        click.echo(f"  failed {result.input}: {result.error}")
    if summary.failed:
        raise DigitEyesError(f"{len(summary.failed)} of {len(summary.results)} input(s) "
                             "failed (listed above)")
