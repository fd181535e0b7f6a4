"""Accuracy benchmark: every registered tracker on a truth that is not its model.

One table (issue 13): tracker x appearance {``model``: images drawn from the tracking
model's own capsules; ``flesh``: the independent surface of docs/appearance.md} x camera
setup {desk 2 cameras, desk 1 camera, webcam 1 camera, egocentric 1 camera, and the
whole-hand stereo rig as the reference} x hand {``exact``: the images come from the
tracking model; ``scaled``: from a hand of :data:`SCALED_HAND` times Appendix A's size,
tracked with the model at 1.0}. Per row: mean and median fingertip error, joint-angle
RMS, palm position and orientation error (:func:`digiteyes.evaluate.evaluate_run`), track
life, frames flagged lost, and the loss flag's precision and recall against the truth of
:mod:`digiteyes.evaluate.truth_loss` (truly lost: mean fingertip error above 30 mm or
any fingertip above 50 mm), with the confusion counts. ``flag_totals`` sums the
confusion counts over every row of an appearance (the issue's target: on ``flesh``,
recall >= 90 % and precision >= 80 %).

Frames: :data:`FRAMES` per sequence (120 at 10 Hz: the index, middle and ring fingers
curl in turn in the setups, :func:`digiteyes.synth.setups.curl_in_turn`), black cloth,
grey, sensor noise 2 grey levels, seed 0. The desk 1-camera row is camera 0 of the desk
pair (the same camera and motion), so it is not rendered twice. Every tracker starts
from the true first state. One thread for OpenCV and numba (as ``bench tracker``).

Run it with ``digiteyes bench accuracy [--json FILE] [--quick]`` (``--trackers`` through
:func:`run`'s ``trackers`` argument); docs/accuracy.md explains the table.
"""

from __future__ import annotations

import time
from collections.abc import Sequence
from dataclasses import replace
from typing import Any

import numpy as np

from digiteyes.benchmarks._machine import emit, machine_info, machine_lines
from digiteyes.benchmarks.tracker import (
    SEED,
    RenderedSequence,
    _number,
    _one_thread,
    _table,
    accuracy_summary,
    render_sequence,
    track_sequence,
)
from digiteyes.errors import DigitEyesError
from digiteyes.evaluate import evaluate_run
from digiteyes.evaluate.truth_loss import flag_scores, truth_loss
from digiteyes.synth.scenarios import Scenario, build_scenario
from digiteyes.synth.setups import setup_scenario
from digiteyes.trackers import tracker_entry, tracker_names

FRAMES = 120
"""Frames per sequence of the full run."""
QUICK_FRAMES = 3
"""Frames per sequence of ``--quick`` (a smoke run)."""
SCALED_HAND = 0.9
"""Size of the ``scaled`` hand relative to Appendix A (the tracking model stays at 1.0)."""
APPEARANCES = ("model", "flesh")
HANDS = ("exact", "scaled")
SETUPS = {
    # row label: (scenario source, cameras of the rendered rig used (None: all))
    "whole-hand 2cam": ("whole-hand", None),
    "desk 2cam": ("desk", None),
    "desk 1cam": ("desk", (0,)),
    "webcam 1cam": ("webcam", None),
    "egocentric 1cam": ("egocentric", None),
}
"""The camera setups; ``whole-hand 2cam`` is the reference of the earlier benchmarks."""
_CAMERAS_RENDERED = {"whole-hand": 2, "desk": 2, "webcam": 1, "egocentric": 1}


def scenario_for(source: str, hand: str, frames: int, seed: int = SEED) -> Scenario:
    """The scenario of a setup ``source`` (``whole-hand`` or a camera setup) with the hand
    size of ``hand`` (``exact``: 1.0, ``scaled``: :data:`SCALED_HAND`)."""
    scale = SCALED_HAND if hand == "scaled" else 1.0
    if source == "whole-hand":
        base = build_scenario("whole-hand", seed=seed, n_frames=frames)
        return replace(base, metadata={**base.metadata, "hand_scale": scale})
    return setup_scenario(source, _CAMERAS_RENDERED[source], hand_scale=scale, seed=seed,
                          n_frames=frames)


def row_figures(sequence: RenderedSequence, outcome: Any) -> dict[str, Any]:
    """The figures of one row: :func:`accuracy_summary`, the median fingertip error, and
    the loss flag scored against :func:`truth_loss` (``flag``: precision, recall and the
    confusion counts; ``truly_lost_frames``)."""
    model = sequence.scenario.model
    out = accuracy_summary(sequence, outcome)
    metrics = evaluate_run(outcome.log, sequence.truth, model, sequence.rig)
    tip = metrics["fingertip_error_mm"]
    out["fingertip_err_mm_median"] = _number(tip and tip.get("median"))
    truth = truth_loss(model, outcome.log.states, sequence.truth.states[:len(outcome.log)],
                       sequence.truth_model)
    out["truly_lost_frames"] = int(truth.lost.sum())
    out["flag"] = flag_scores(outcome.log.lost, truth.lost)
    out["finger_flag"] = finger_scores(outcome.finger_lost, truth.tip_names,
                                       truth.finger_lost)
    return out


def finger_scores(flags: Sequence[dict[str, bool]], tip_names: Sequence[str],
                  lost: np.ndarray) -> dict[str, Any] | None:
    """The per-finger loss flags (one dict digit -> bool per frame) scored against the
    per-finger truth (T, F) over every (frame, finger) the tracker judged; None when it
    judged none (a tracker without per-finger flags)."""
    digits = [name.split(".")[0] for name in tip_names]
    pairs = [(bool(frame[d]), bool(lost[t, f])) for t, frame in enumerate(flags)
             for f, d in enumerate(digits) if d in frame]
    if not pairs:
        return None
    flagged, truth = np.array(pairs).T
    return flag_scores(flagged, truth) | {"judged": len(pairs)}


def _totals(rows: list[dict[str, Any]], key: str = "flag") -> dict[str, Any] | None:
    scored = [r[key] for r in rows if r.get(key)]
    if not scored:
        return None
    tp, fp, fn = (sum(s[k] for s in scored)
                  for k in ("true_positive", "false_positive", "false_negative"))
    frames = sum(r["frames"] for r in rows) if key == "flag" \
        else sum(s["judged"] for s in scored)
    return {"precision": tp / (tp + fp) if tp + fp else None,
            "recall": tp / (tp + fn) if tp + fn else None, "true_positive": tp,
            "false_positive": fp, "false_negative": fn,
            "true_negative": frames - tp - fp - fn, "frames": frames}


def run(json_path: str | None = None, quick: bool = False,
        trackers: Sequence[str] | None = None, frames: int | None = None,
        progress: bool = False) -> dict[str, Any]:
    """Run the table, print it, optionally write JSON; return the figures.

    ``trackers``: names of registered trackers (default: all of them,
    :func:`~digiteyes.trackers.tracker_names`); ``frames`` overrides the frames per
    sequence (:data:`FRAMES`, or :data:`QUICK_FRAMES` with ``quick``).

    JSON: ``rows`` (a list; each row ``tracker``, ``appearance``, ``setup``, ``hand`` and
    the figures of :func:`row_figures`), ``flag_totals`` [tracker][appearance], and
    ``finger_flag_totals`` [tracker][appearance] (the per-finger flags over every
    (frame, finger) judged; None for a tracker without them), ``settings``, ``machine``,
    ``threads``, ``wall_seconds``. A row's ``finger_flag`` scores
    ``TrackResult.finger_lost`` against the per-finger truth (tip error above 50 mm).
    """
    names = list(tracker_names()) if trackers is None else list(trackers)
    for name in names:
        tracker_entry(name)
    n = frames or (QUICK_FRAMES if quick else FRAMES)
    if n < 2:
        raise DigitEyesError(f"bench accuracy needs at least 2 frames per sequence, got {n}")
    started = time.perf_counter()
    machine = machine_info()
    result: dict[str, Any] = {
        "benchmark": "accuracy", "quick": quick, "machine": machine, "trackers": names,
        "settings": {"frames": n, "seed": SEED, "scaled_hand": SCALED_HAND,
                     "background": "black", "image": "640x480 grey",
                     "truly_lost": "mean fingertip error > 30 mm or any tip > 50 mm"},
    }
    rows: list[dict[str, Any]] = []
    with _one_thread() as threads:
        result["threads"] = threads
        print("\n".join([f"accuracy benchmark{' (quick)' if quick else ''}, {n} frames "
                         "per sequence", *machine_lines(machine), f"threads: {threads}", ""]),
              flush=True)
        for appearance in APPEARANCES:
            for hand in HANDS:
                rendered: dict[str, RenderedSequence] = {}
                for label, (source, cameras) in SETUPS.items():
                    if source not in rendered:
                        rendered[source] = render_sequence(
                            scenario_for(source, hand, n), appearance=appearance,
                            progress=progress)
                    sequence = rendered[source].cameras(cameras)
                    for name in names:
                        options = tracker_entry(name).options_type()
                        outcome = track_sequence(sequence, options, f"{name} {label}",
                                                 progress, tracker=name)
                        row = {"tracker": name, "appearance": appearance, "setup": label,
                               "hand": hand} | row_figures(sequence, outcome)
                        rows.append(row)
                        print(f"{name} / {appearance} / {label} / {hand}: tip "
                              f"{_f(row['fingertip_err_mm_mean'])} mm, "
                              f"{row['flag']['flagged_frames']} flagged, "
                              f"{row['truly_lost_frames']} truly lost", flush=True)
    result["rows"] = rows
    result["flag_totals"], result["finger_flag_totals"] = (
        {name: {a: _totals([r for r in rows if r["tracker"] == name
                            and r["appearance"] == a], key) for a in APPEARANCES}
         for name in names} for key in ("flag", "finger_flag"))
    result["wall_seconds"] = time.perf_counter() - started
    lines = ["", format_rows(rows), "", format_side_by_side(rows), "", format_totals(result),
             f"benchmark wall time {result['wall_seconds']:.0f} s"]
    return emit(result, "\n".join(lines), json_path)


def _f(value: float | None, fmt: str = ".1f") -> str:
    return "n/a" if value is None else f"{value:{fmt}}"


COLUMNS = ("tracker", "appearance", "setup", "hand", "tip mean", "tip median", "joint RMS",
           "palm mm", "palm deg", "life", "flagged", "truly lost", "precision", "recall")


def format_rows(rows: Sequence[dict[str, Any]], header: bool = True) -> str:
    """Rows of the table (mm, degrees, frames; precision and recall in %)."""
    cells = [[r["tracker"], r["appearance"], r["setup"], r["hand"],
              _f(r["fingertip_err_mm_mean"]), _f(r["fingertip_err_mm_median"]),
              _f(r["joint_angle_err_deg_rms"]), _f(r["palm_pos_err_mm_mean"]),
              _f(r["palm_rot_err_deg_mean"]), f"{r['track_life_frames']}/{r['frames']}",
              str(r["flag"]["flagged_frames"]), str(r["truly_lost_frames"]),
              _pct(r["flag"]["precision"]), _pct(r["flag"]["recall"])] for r in rows]
    lines = _table(list(COLUMNS), cells)
    return "\n".join(lines if header else lines[2:])


def _pct(value: float | None) -> str:
    return "n/a" if value is None else f"{100 * value:.0f}%"


def format_totals(result: dict[str, Any]) -> str:
    """The loss flag over all rows of each tracker and appearance (confusion counts), and
    the per-finger flags over every (frame, finger) judged."""
    cells = [[name + (" (per finger)" if key.startswith("finger") else ""), appearance,
              _pct(t["precision"]), _pct(t["recall"]),
              str(t["true_positive"]), str(t["false_positive"]), str(t["false_negative"]),
              str(t["true_negative"])]
             for key in ("flag_totals", "finger_flag_totals")
             for name, by_appearance in result[key].items()
             for appearance, t in by_appearance.items() if t]
    return "\n".join(["loss flag against truth, all rows (targets on flesh: recall >= 90 %, "
                      "precision >= 80 %)",
                      *_table(["tracker", "appearance", "precision", "recall", "TP", "FP",
                               "FN", "TN"], cells)])


SIDE_FIGURES = (("tip mean", "fingertip_err_mm_mean"), ("tip median", "fingertip_err_mm_median"),
                ("joint RMS", "joint_angle_err_deg_rms"), ("palm mm", "palm_pos_err_mm_mean"),
                ("palm deg", "palm_rot_err_deg_mean"))


def format_side_by_side(rows: Sequence[dict[str, Any]], markdown: bool = False) -> str:
    """The table with the two appearances side by side (``model | flesh`` in each cell):
    a row per tracker, setup and hand; ``markdown`` for docs/accuracy.md."""
    by_key = {(r["tracker"], r["setup"], r["hand"], r["appearance"]): r for r in rows}
    keys = list(dict.fromkeys((r["tracker"], r["setup"], r["hand"]) for r in rows))
    header = ["tracker", "setup", "hand", *(label for label, _ in SIDE_FIGURES), "life",
              "lost: truly / flagged / caught"]
    cells = []
    for tracker, setup, hand in keys:
        pair = [by_key.get((tracker, setup, hand, a)) for a in APPEARANCES]
        row = [tracker, setup, hand]
        for _, key in SIDE_FIGURES:
            row.append(" | ".join(_f(r[key]) if r else "-" for r in pair))
        row.append(" | ".join(f"{r['track_life_frames']}/{r['frames']}" if r else "-"
                              for r in pair))
        row.append(" | ".join(f"{r['truly_lost_frames']}/{r['flag']['flagged_frames']}/"
                              f"{r['flag']['true_positive']}" if r else "-" for r in pair))
        cells.append(row)
    if markdown:
        return "\n".join(["| " + " | ".join(header) + " |",
                          "|" + "---|" * len(header),
                          *("| " + " | ".join(c.replace(" | ", " \\| ") for c in row) + " |"
                            for row in cells)])
    return "\n".join(["figures as model | flesh appearance (mm, degrees, frames)",
                      *_table(header, cells)])
