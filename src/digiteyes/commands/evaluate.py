"""``digiteyes evaluate RESULT_DIR GT_DIR``: accuracy of a tracker run against ground truth."""

from __future__ import annotations

from pathlib import Path

import click


@click.command()
@click.argument("result", metavar="RESULT_DIR", type=click.Path(exists=True, path_type=Path))
@click.argument("gt_dir", metavar="GT_DIR",
                type=click.Path(exists=True, file_okay=False, path_type=Path))
@click.option("-o", "--output", type=click.Path(file_okay=False, path_type=Path),
              help="Folder for metrics.json, report.md and plots [default: RESULT_DIR/evaluation].")
@click.option("--loss-threshold-mm", type=click.FloatRange(min=0, min_open=True),
              default=20.0, show_default=True,
              help="Mean fingertip error above which a frame counts as track loss.")
def evaluate(result: Path, gt_dir: Path, output: Path | None, loss_threshold_mm: float) -> None:
    """Compare the state log of a run (RESULT_DIR/states.csv) with the ground truth of the
    sequence GT_DIR; print the headline metrics and write a report.

    RESULT_DIR may also be the state-log CSV itself.
    """
    from digiteyes.errors import DatasetError
    from digiteyes.evaluate import evaluate_run, headline_rows, write_report
    from digiteyes.evaluate.report_page import write_report_page
    from digiteyes.io import open_sequence, read_state_log
    from digiteyes.io.track_extras import track_residual_unit

    log_path = result if result.is_file() else result / "states.csv"
    with open_sequence(gt_dir) as seq:
        if seq.truth is None:
            raise DatasetError(f"{gt_dir}: the sequence has no ground truth ('truth' is null "
                               "in sequence.json)")
        log = read_state_log(log_path, seq.model)
        metrics = evaluate_run(log, seq.truth, seq.model, seq.rig,
                               loss_threshold_mm=loss_threshold_mm)
        metrics["run"]["residual_unit"] = track_residual_unit(log_path.parent)
        out = output or (log_path.parent / "evaluation")
        report = write_report(metrics, log, seq.truth, seq.model, out, fps=seq.fps,
                              title=f"Evaluation of {log_path} on {seq.name}")
    page = write_report_page(out, title=f"Evaluation of {log_path} on {seq.name}")
    rows = headline_rows(metrics)
    width = max(len(label) for label, _ in rows)
    click.echo(f"{seq.name}: {metrics['run']['frames']} frames, model {seq.model.name}")
    for label, value in rows:
        click.echo(f"  {label:<{width}}  {value}")
    click.echo(f"wrote {report}, {page} and {out / 'metrics.json'}")
