"""Evaluation reports: metrics.json, report.md and PNG plots in one folder.

The plots follow the thesis's trajectory figures (palm pose, Fig. 4.7; joint angles of the
index finger and the thumb, Fig. 4.8) with the ground truth beside the estimate, plus the
per-frame fingertip error and per-finger joint-angle errors. docs/evaluation.md describes
every entry.
"""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

import numpy as np

from digiteyes.errors import DatasetError
from digiteyes.io.dataset import GroundTruth
from digiteyes.io.state_log import StateLog
from digiteyes.kinematics import KinematicModel
from digiteyes.viz.plots import (
    plot_error_bars,
    plot_error_series,
    save_figure,
)
from digiteyes.viz.trajectory import JOINTS_PLOT, PALM_PLOT, write_trajectory_plots


def _clean(value: Any) -> Any:
    """Plain JSON values: numpy scalars to Python, NaN and infinities to None."""
    if isinstance(value, dict):
        return {str(k): _clean(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [_clean(v) for v in value]
    if isinstance(value, np.generic):
        value = value.item()
    if isinstance(value, float) and not math.isfinite(value):
        return None
    return value


def _fmt(value: float | None, unit: str, digits: int = 2) -> str:
    return "n/a" if value is None else f"{value:.{digits}f} {unit}".rstrip()


def headline_rows(metrics: dict[str, Any]) -> list[tuple[str, str]]:
    """The headline numbers of :func:`~digiteyes.evaluate.metrics.evaluate_run` as
    (label, formatted value) rows, for the CLI table and the report."""
    rows: list[tuple[str, str]] = []

    def pair(label: str, first: float, second: float, unit: str) -> None:
        rows.append((label, f"{_fmt(first, '')} / {_fmt(second, unit)}"))

    tip = metrics.get("fingertip_error_mm")
    if tip:
        rows.append(("fingertip error mean / median / max",
                     f"{_fmt(tip['mean'], '')} / {_fmt(tip['median'], '')} / "
                     f"{_fmt(tip['max'], 'mm')}"))
    kp = metrics.get("keypoint_error_mm")
    if kp:
        pair("joint (keypoint) 3D error mean / max", kp["mean"], kp["max"], "mm")
    ang = metrics.get("joint_angle_error_deg")
    if ang:
        pair("joint angle error RMS / mean abs", ang["rms"], ang["mean_abs"], "deg")
    palm = metrics.get("palm")
    if palm:
        position, orientation = palm["position_error_mm"], palm["orientation_error_deg"]
        pair("palm position error mean / max", position["mean"], position["max"], "mm")
        pair("palm orientation error mean / max", orientation["mean"], orientation["max"],
             "deg")
    rep = metrics.get("reprojection_error_px")
    if rep:
        pair("2D reprojection error mean / max", rep["mean"], rep["max"], "px")
    life = metrics["track_life"]
    lost = "" if life["lost_at_frame"] is None else \
        f" (lost at frame {life['lost_at_frame']}: {life['reason']})"
    rows.append(("track life", f"{life['frames']} of {life['of_frames']} frames{lost}"))
    run = metrics["run"]
    rows.append(("frames flagged lost by the tracker", str(run["lost_frames"])))
    res = run["residual_rms_px"]
    rows.append(("tracker residual RMS, mean", _fmt(res["mean"] if res else None,
                                                    run.get("residual_unit", "px"))))
    rows.append(("iterations per frame, mean", _fmt(run["iterations_mean"], "", 1)))
    rows.append(("time per frame, mean", _fmt(1000 * run["time_s_mean"], "ms", 1)))
    return rows


def _group_table(title: str, groups: dict[str, dict], keys: tuple[str, ...], unit: str
                 ) -> list[str]:
    lines = [f"### {title}", "", "| | " + " | ".join(f"{k} ({unit})" for k in keys) + " |",
             "|---" * (len(keys) + 1) + "|"]
    for name, stats in groups.items():
        cells = ["n/a" if stats.get(k) is None else f"{stats[k]:.2f}" for k in keys]
        lines.append(f"| {name} | " + " | ".join(cells) + " |")
    return [*lines, ""]


def write_report(metrics: dict[str, Any], estimated: StateLog, truth: GroundTruth,
                 model: KinematicModel, out_dir: str | Path, *, fps: float | None = None,
                 title: str = "") -> Path:
    """Write ``metrics.json``, PNG plots and ``report.md`` into ``out_dir``; return the
    report's path.

    ``metrics`` comes from :func:`~digiteyes.evaluate.metrics.evaluate_run` for the same
    ``estimated`` log and ``truth``. With ``fps`` the plots' time axis is in seconds,
    otherwise in frames.
    """
    out = Path(out_dir)
    try:
        out.mkdir(parents=True, exist_ok=True)
        (out / "metrics.json").write_text(
            json.dumps(_clean(metrics), indent=2, allow_nan=False) + "\n", encoding="utf-8")
    except OSError as exc:
        raise DatasetError(f"{out}: cannot write the evaluation ({exc.strerror or exc})"
                           ) from None
    frames = np.asarray(estimated.frames, dtype=int)
    t = frames / fps if fps else frames.astype(float)
    xlabel = "time (s)" if fps else "frame"
    per_frame = metrics["per_frame"]
    lost = np.asarray(per_frame["lost"], dtype=bool)
    figures: list[tuple[str, str]] = []

    def series(values: list) -> np.ndarray:
        return np.array([np.nan if v is None else v for v in values], dtype=float)

    life = metrics["track_life"]
    if per_frame["fingertip_error_mm_per_tip"]:
        curves = {k: series(v) for k, v in per_frame["fingertip_error_mm_per_tip"].items()}
        label = "fingertip 3D error (mm)"
    else:
        curves = {"mean keypoint": series(per_frame["keypoint_error_mm"] or [])}
        label = "keypoint 3D error (mm)"
    if any(len(c) for c in curves.values()):
        fig = plot_error_series(t, curves, ylabel=label, xlabel=xlabel,
                                threshold=life["threshold_mm"], lost=lost,
                                title="Per-frame 3D error")
        figures.append(("Per-frame 3D error",
                        save_figure(fig, out / "fingertip_error.png").name))

    true_states = None if truth.states is None else truth.states[frames]
    plots = write_trajectory_plots(model, estimated.states, out, truth=true_states, t=t,
                                   xlabel=xlabel)
    captions = {PALM_PLOT: "Palm rotation and translation (thesis Fig. 4.7 style)",
                JOINTS_PLOT: "Joint angles (thesis Fig. 4.8 style)"}
    figures += [(captions[key], path.name) for key, path in plots.items()]

    angles = metrics.get("joint_angle_error_deg")
    if angles:
        fig = plot_error_bars(angles["per_finger"], ylabel="joint angle error (deg)",
                              title="Joint-angle error per finger")
        figures.append(("Joint-angle error per finger",
                        save_figure(fig, out / "joint_angle_error.png").name))

    lines = [f"# {title or 'Tracking evaluation'}", "",
             f"Model `{metrics['model']}`, frames {metrics['run']['first_frame']}.."
             f"{metrics['run']['last_frame']} ({metrics['run']['frames']} evaluated of "
             f"{metrics['run']['truth_frames']} with ground truth). Definitions: "
             "docs/evaluation.md.", "", "| metric | value |", "|---|---|"]
    lines += [f"| {label} | {value} |" for label, value in headline_rows(metrics)]
    lines.append("")
    if metrics.get("fingertip_error_mm"):
        lines += _group_table("Fingertip 3D error", metrics["fingertip_error_mm"]["per_tip"],
                              ("mean", "median", "max"), "mm")
    if angles:
        lines += _group_table("Joint-angle error per finger", angles["per_finger"],
                              ("rms", "mean_abs", "max_abs"), "deg")
        lines += _group_table("Joint-angle error per joint type", angles["per_joint_type"],
                              ("rms", "mean_abs", "max_abs"), "deg")
    if metrics.get("reprojection_error_px"):
        lines += _group_table("2D reprojection error per camera",
                              metrics["reprojection_error_px"]["per_camera"],
                              ("mean", "median", "max"), "px")
    for caption, name in figures:
        lines += [f"### {caption}", "", f"![{caption}]({name})", ""]
    report = out / "report.md"
    try:
        report.write_text("\n".join(lines), encoding="utf-8")
    except OSError as exc:
        raise DatasetError(f"{report}: cannot write ({exc.strerror or exc})") from None
    return report
