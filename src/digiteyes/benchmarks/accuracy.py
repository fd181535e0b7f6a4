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
grey, sensor noise 2 grey levels, seed 0. The slow particle trackers track the first
:data:`TRACKER_FRAMES` frames of the same renders (at least the index finger's whole
curl, 40 frames), so that the table fits in about 15 minutes on two cores; every row is
there, and each row says its frames. The desk 1-camera row is camera 0 of the desk pair
(the same camera and motion), so it is not rendered twice. Every tracker starts from the
true first state. One thread for OpenCV and numba per process (as ``bench tracker``);
the sequences (appearance x hand x scenario) are rendered and tracked in
:data:`WORKERS` worker processes.

Run it with ``digiteyes bench accuracy [--json FILE] [--quick] [--trackers A,B]
[--workers N]``; docs/accuracy.md explains the table.
"""

from __future__ import annotations

import multiprocessing
import time
from collections.abc import Sequence
from concurrent.futures import ProcessPoolExecutor, as_completed
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
from digiteyes.camera import Rig
from digiteyes.camera.default import default_camera
from digiteyes.errors import DigitEyesError
from digiteyes.evaluate import evaluate_run
from digiteyes.evaluate.truth_loss import TRULY_LOST_MEAN_MM, flag_scores, truth_loss
from digiteyes.kinematics import load_model
from digiteyes.synth.scenarios import Scenario, build_scenario
from digiteyes.synth.setups import setup_scenario
from digiteyes.trackers import create_tracker, tracker_entry, tracker_names

FRAMES = 120
"""Frames per sequence of the full run."""
TRACKER_FRAMES = {"divide-conquer": 60, "condensation": 40, "random-search": 40}
"""Frames per sequence of the slow particle trackers in the full run (the first frames of
the renders of :data:`FRAMES`; 40 frames hold the index finger's whole curl and
reopening). Trackers not named here track :data:`FRAMES`."""
QUICK_FRAMES = 3
"""Frames per sequence of ``--quick`` (a smoke run), every tracker."""
WORKERS = 2
"""Worker processes of the full run (the benchmark machine has two cores)."""
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
    """The figures of one row: :func:`accuracy_summary`, the median fingertip error, the
    worst frame's mean fingertip error and the frames whose mean exceeds
    :data:`~digiteyes.evaluate.truth_loss.TRULY_LOST_MEAN_MM` (issue 14's desk target:
    none), and the loss flag scored against :func:`truth_loss` (``flag``: precision,
    recall and the confusion counts; ``truly_lost_frames``)."""
    model = sequence.scenario.model
    out = accuracy_summary(sequence, outcome)
    metrics = evaluate_run(outcome.log, sequence.truth, model, sequence.rig)
    tip = metrics["fingertip_error_mm"]
    out["fingertip_err_mm_median"] = _number(tip and tip.get("median"))
    per_frame = np.array([np.nan if e is None else e
                          for e in metrics["per_frame"]["fingertip_error_mm"] or []], dtype=float)
    seen = per_frame[np.isfinite(per_frame)]
    out["worst_frame_tip_err_mm"] = float(seen.max()) if seen.size else None
    out["frames_tip_err_above_30mm"] = int((seen > TRULY_LOST_MEAN_MM).sum())
    truth = truth_loss(model, outcome.log.states, sequence.truth.states[:len(outcome.log)],
                       sequence.truth_model, hand_scale=outcome.log.hand_scale)
    out["truly_lost_frames"] = int(truth.lost.sum())
    out["flag"] = flag_scores(outcome.log.lost, truth.lost)
    out["timeline"] = {"flagged": _bits(outcome.log.lost), "truly_lost": _bits(truth.lost)}
    out["finger_flag"] = finger_scores(outcome.finger_lost, truth.tip_names,
                                       truth.finger_lost)
    return out


def _bits(flags: np.ndarray) -> str:
    """Per-frame flags (T,) bool as a string of ``0`` and ``1``."""
    return "".join("1" if f else "0" for f in np.asarray(flags, dtype=bool))


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


def flag_totals(rows: list[dict[str, Any]], key: str = "flag") -> dict[str, Any] | None:
    """The loss flag's confusion counts summed over ``rows`` (each with ``key``, a
    :func:`~digiteyes.evaluate.truth_loss.flag_scores` result, and ``frames``), with
    precision and recall; ``key="finger_flag"`` counts the (frame, finger) pairs judged.
    None when no row was scored."""
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


def frames_per_tracker(names: Sequence[str], quick: bool = False,
                       frames: int | None = None) -> dict[str, int]:
    """Frames per sequence of each tracker: ``frames`` for all when given, else
    :data:`QUICK_FRAMES` with ``quick``, else :data:`TRACKER_FRAMES` or :data:`FRAMES`.
    Raises :class:`DigitEyesError` below 2 frames."""
    out = {name: frames or (QUICK_FRAMES if quick else TRACKER_FRAMES.get(name, FRAMES))
           for name in names}
    for name, n in out.items():
        if n < 2:
            raise DigitEyesError(f"bench accuracy needs at least 2 frames per sequence, "
                                 f"got {n} for {name!r}")
    return out


def available_trackers() -> list[str]:
    """The registered trackers that can run here, in registry order: one that needs an
    optional extra this installation lacks (``features+keypoints`` without MediaPipe) is
    left out, with a line saying why."""
    names = []
    model, rig = load_model("hand"), Rig((default_camera(640, 480),))
    for name in tracker_names():
        try:
            create_tracker(name, model, rig)
        except DigitEyesError as error:
            print(f"accuracy: tracker {name} left out: {error}", flush=True)
            continue
        names.append(name)
    return names


def source_rows(appearance: str, hand: str, source: str, frames: dict[str, int],
                progress: bool = False, seed: int = SEED) -> list[dict[str, Any]]:
    """Render one scenario ``source`` (``whole-hand`` or a camera setup) in ``appearance``
    with the hand of ``hand``, for as many frames as the longest of ``frames`` (tracker
    name -> frames), its motion and noise drawn from ``seed``, and track each setup of
    :data:`SETUPS` drawn from it with every tracker over its first ``frames[name]``
    frames; the rows of the table (one thread)."""
    rows = []
    with _one_thread():
        rendered = render_sequence(scenario_for(source, hand, max(frames.values()), seed),
                                   appearance=appearance, progress=progress, seed=seed)
        for label, (setup_source, cameras) in SETUPS.items():
            if setup_source != source:
                continue
            for name, n in frames.items():
                sequence = rendered.cameras(cameras).first(n)
                options = tracker_entry(name).options_type()
                outcome = track_sequence(sequence, options, f"{name} {label}", progress,
                                         tracker=name)
                rows.append({"tracker": name, "appearance": appearance, "setup": label,
                             "hand": hand} | row_figures(sequence, outcome))
    return rows


def _jobs() -> list[tuple[str, str, str]]:
    """(appearance, hand, source) of every rendered sequence, the costliest first (the
    desk renders serve two setups)."""
    sources = sorted(dict.fromkeys(source for source, _ in SETUPS.values()),
                     key=lambda src: -sum(s == src for s, _ in SETUPS.values()))
    return [(a, h, src) for src in sources for a in APPEARANCES[::-1] for h in HANDS]


def _row_order(row: dict[str, Any], names: Sequence[str]) -> tuple[int, ...]:
    return (APPEARANCES.index(row["appearance"]), HANDS.index(row["hand"]),
            list(SETUPS).index(row["setup"]), list(names).index(row["tracker"]))


def run(json_path: str | None = None, quick: bool = False,
        trackers: Sequence[str] | None = None, frames: int | None = None,
        progress: bool = False, workers: int | None = None,
        seed: int = SEED) -> dict[str, Any]:
    """Run the table, print it, optionally write JSON; return the figures.

    ``trackers``: names of registered trackers (default: all of them,
    :func:`~digiteyes.trackers.tracker_names`); ``frames`` overrides the frames per
    sequence of every tracker (:func:`frames_per_tracker`); ``workers``: processes that
    render and track the sequences (default :data:`WORKERS`, 1 with ``quick``; 1 runs in
    this process); ``seed`` draws the scenarios' motions and the sensor noise (the
    committed table is :data:`SEED`'s; another seed asks whether its figures hold for
    other motions of the same kind).

    JSON: ``rows`` (a list; each row ``tracker``, ``appearance``, ``setup``, ``hand`` and
    the figures of :func:`row_figures`, ``frames`` among them), ``flag_totals``
    [tracker][appearance], ``finger_flag_totals`` [tracker][appearance] (the per-finger
    flags over every (frame, finger) judged; None for a tracker without them),
    ``flag_totals_all`` [appearance] and ``finger_flag_totals_all`` [appearance] (over
    the rows of every tracker), ``settings`` (``frames``: tracker -> frames per
    sequence), ``machine``, ``threads``, ``wall_seconds``. A row's ``finger_flag``
    scores ``TrackResult.finger_lost`` against the per-finger truth (tip error above
    50 mm); its ``timeline`` has the frames ``flagged`` and ``truly_lost`` as strings of
    ``0`` and ``1``, one character per frame.
    """
    names = available_trackers() if trackers is None else list(trackers)
    for name in names:
        tracker_entry(name)
    per_tracker = frames_per_tracker(names, quick, frames)
    n_workers = workers or (1 if quick else WORKERS)
    if n_workers < 1:
        raise DigitEyesError(f"bench accuracy needs at least 1 worker, got {n_workers}")
    started = time.perf_counter()
    machine = machine_info()
    result: dict[str, Any] = {
        "benchmark": "accuracy", "quick": quick, "machine": machine, "trackers": names,
        "settings": {"frames": per_tracker, "rendered_frames": max(per_tracker.values()),
                     "workers": n_workers, "seed": seed, "scaled_hand": SCALED_HAND,
                     "background": "black", "image": "640x480 grey",
                     "truly_lost": "mean fingertip error > 30 mm or any tip > 50 mm"},
    }
    with _one_thread() as threads:
        result["threads"] = f"per process: {threads}"
    print("\n".join([f"accuracy benchmark{' (quick)' if quick else ''}, seed {seed}, frames "
                     "per sequence: " + ", ".join(f"{k} {v}" for k, v in per_tracker.items()),
                     *machine_lines(machine), f"threads: {result['threads']}",
                     f"worker processes: {n_workers}", ""]), flush=True)
    rows: list[dict[str, Any]] = []
    jobs = _jobs()
    if n_workers == 1:
        for job in jobs:
            rows += _report(source_rows(*job, per_tracker, progress, seed))
    else:
        context = multiprocessing.get_context("spawn")
        with ProcessPoolExecutor(n_workers, mp_context=context) as pool:
            futures = [pool.submit(source_rows, *job, per_tracker, False, seed)
                       for job in jobs]
            for future in as_completed(futures):
                rows += _report(future.result())
    rows.sort(key=lambda row: _row_order(row, names))
    result["rows"] = rows
    result["flag_totals"], result["finger_flag_totals"] = (
        {name: {a: flag_totals([r for r in rows if r["tracker"] == name
                            and r["appearance"] == a], key) for a in APPEARANCES}
         for name in names} for key in ("flag", "finger_flag"))
    result["flag_totals_all"], result["finger_flag_totals_all"] = (
        {a: flag_totals([r for r in rows if r["appearance"] == a], key) for a in APPEARANCES}
        for key in ("flag", "finger_flag"))
    result["wall_seconds"] = time.perf_counter() - started
    lines = ["", format_rows(rows), "", format_side_by_side(rows), "", format_totals(result),
             f"benchmark wall time {result['wall_seconds']:.0f} s"]
    return emit(result, "\n".join(lines), json_path)


def _report(rows: list[dict[str, Any]]) -> list[dict[str, Any]]:
    """Print one line per row as the rows arrive; returns them."""
    for row in rows:
        print(f"{row['tracker']} / {row['appearance']} / {row['setup']} / {row['hand']}: "
              f"{row['frames']} frames, tip {_f(row['fingertip_err_mm_mean'])} mm, "
              f"{row['flag']['flagged_frames']} flagged, {row['truly_lost_frames']} truly "
              "lost", flush=True)
    return rows


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
              percent(r["flag"]["precision"]), percent(r["flag"]["recall"])] for r in rows]
    lines = _table(list(COLUMNS), cells)
    return "\n".join(lines if header else lines[2:])


def percent(value: float | None, missing: str = "n/a") -> str:
    """A fraction as a whole percentage (``0.754`` -> ``"75%"``), ``missing`` for None."""
    return missing if value is None else f"{100 * value:.0f}%"


def precision_recall(flag: dict[str, Any], missing: str = "-") -> str:
    """``"precision / recall"`` of a flag's scores (:func:`flag_totals`) as percentages."""
    return f"{percent(flag['precision'], missing)} / {percent(flag['recall'], missing)}"


def format_totals(result: dict[str, Any]) -> str:
    """The loss flag over all rows of each tracker and appearance (confusion counts), and
    the per-finger flags over every (frame, finger) judged."""
    totals = {key: {**result[key], "all trackers": result[f"{key}_all"]}
              for key in ("flag_totals", "finger_flag_totals")}
    cells = [[name + (" (per finger)" if key.startswith("finger") else ""), appearance,
              percent(t["precision"]), percent(t["recall"]),
              str(t["true_positive"]), str(t["false_positive"]), str(t["false_negative"]),
              str(t["true_negative"])]
             for key in ("flag_totals", "finger_flag_totals")
             for name, by_appearance in totals[key].items()
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
