"""``digiteyes demo``: the main job on a built-in default, end to end.

Renders the ``whole-hand`` scenario (thesis Sec. 4.3.3: two cameras verged on a tabletop,
200 frames of palm motion with finger articulation), tracks it from its initial state with
the DigitEyes feature tracker, evaluates the track against the ground truth and prints
where the overlay video, the plots and the report are, with the headline figures.
"""

from __future__ import annotations

from pathlib import Path

import click

from digiteyes.commands import _demo_folder
from digiteyes.commands.track import print_run, tracker_options
from digiteyes.evaluate import evaluate_run, headline_rows, write_report
from digiteyes.io import open_sequence, read_state_log
from digiteyes.pipeline import run_tracker
from digiteyes.synth.scenarios import build_scenario
from digiteyes.synth.sequence import render_scenario
from digiteyes.trackers import DEFAULT_TRACKER, create_tracker
from digiteyes.warmup import COMPILE_MESSAGE, compile_in_background


@click.command()
@click.option("-o", "--output", type=click.Path(file_okay=False), default="digiteyes-demo",
              show_default=True,
              help="Folder for everything the demo writes (an earlier demo's files are "
                   "replaced, nothing else).")
@click.option("--scenario", "scenario_name", default="whole-hand", show_default=True,
              help="Scenario to render and track (docs/scenarios.md).")
@click.option("--frames", type=click.IntRange(min=2), default=None,
              help="Number of frames (default: the scenario's length, 200 for whole-hand).")
@click.option("--iterations", type=click.IntRange(min=1), default=5, show_default=True,
              help="Gauss-Newton iterations per frame.")
@click.option("--seed", type=click.IntRange(min=0), default=0, show_default=True)
@click.option("--quiet", is_flag=True, help="No progress bars.")
def demo(output: str, scenario_name: str, frames: int | None, iterations: int, seed: int,
         quiet: bool) -> None:
    """Render a synthetic sequence, track it, evaluate against ground truth."""
    out = Path(output)
    scenario = build_scenario(scenario_name, seed=seed, n_frames=frames)
    _demo_folder.prepare(out)
    try:
        _run_demo(out, scenario, iterations, seed, quiet)
    finally:
        _demo_folder.record(out)


def _run_demo(out: Path, scenario, iterations: int, seed: int, quiet: bool) -> None:
    compiling = compile_in_background(scenario.name)
    if compiling is not None:
        click.echo(COMPILE_MESSAGE)
    click.echo(f"1/3 rendering {scenario.name}: {scenario.n_frames} frames x "
               f"{len(scenario.rig)} camera(s) -> {out / 'sequence'}")
    try:
        render_scenario(scenario, out / "sequence", seed=seed, progress=not quiet)
    finally:
        if compiling is not None:
            compiling.wait()
    sequence = open_sequence(out / "sequence")

    click.echo(f"2/3 tracking with {iterations} Gauss-Newton iterations per frame")
    options = tracker_options(iterations, 20.0, "default", sequence.model, None, "none")
    tracker = create_tracker(DEFAULT_TRACKER, sequence.model, sequence.rig,
                             **vars(options))
    run = run_tracker(tracker, sequence.model, sequence.rig, iter(sequence),
                      sequence.initial_state, out / "track", fps=sequence.fps,
                      total=sequence.n_frames, progress=not quiet,
                      tracker_name=DEFAULT_TRACKER)
    print_run(run)

    click.echo("3/3 evaluating against ground truth")
    estimated = read_state_log(run.files["states"], sequence.model)
    metrics = evaluate_run(estimated, sequence.truth, sequence.model, sequence.rig)
    metrics["speed"] = run.to_json()
    report = write_report(metrics, estimated, sequence.truth, sequence.model,
                          out / "evaluation", fps=sequence.fps,
                          title=f"digiteyes demo: {scenario.name}")
    for label, value in headline_rows(metrics):
        click.echo(f"  {label:<34} {value}")
    click.echo(f"report: {report}")
    if run.interrupted:
        raise KeyboardInterrupt
