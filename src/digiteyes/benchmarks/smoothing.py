"""``digiteyes bench smoothing``: jitter and lag of the One Euro filter against truth.

Two rendered sequences are tracked by the feature tracker (default options) from their
true first state: a *still* hand (the first state of ``whole-hand`` held for every frame,
so any motion of the estimate is tracker jitter from image noise) and the *moving*
``whole-hand`` sequence itself (thesis Sec. 4.3.3 speeds). Figures, before and after
:func:`~digiteyes.filters.one_euro_filter`:

* jitter: RMS frame-to-frame displacement of the keypoints (joint centres, tips, palm
  centre), mm, on the still hand after a warm-up of :data:`WARM_UP` frames (the truth does
  not move, so all of it is noise); also the RMS frame-to-frame change of the joint
  angles, degrees;
* lag: the time shift ``s`` (frames) that minimises the RMS keypoint error between the
  estimate at frame ``t`` and the truth at ``t - s`` (truth interpolated linearly),
  searched on a grid of :data:`LAG_STEP` frames, on the moving hand; the filter's added lag
  is the filtered lag minus the raw one (the target, one frame, is judged at the
  scenario's 10 frames/s; the pairs filmed faster report it in ms too);
* error: mean keypoint error, mm, on both sequences;
* slow motion: the defaults on the true ``whole-hand`` states (no tracker, no noise)
  slowed :data:`SLOW_FACTORS` times (states interpolated on the manifold): the lag in
  frames and the mean and largest keypoint error it causes, mm. Below the dead band the
  resting cutoff holds the output, but the gap to the measurement is itself a speed, so
  the error stays bounded while the lag in frames grows.

A grid of settings (``min_cutoff_hz`` x ``beta_per_mm_s`` x ``d_cutoff_hz`` x
``deadband_mm_s``; a dead band of 0 is the published filter) is run on the same two tracks;
the table marks the settings meeting the targets (jitter down 5x, at most one frame of
added lag). :func:`choose` applies the rule that picked the defaults (the largest jitter
ratio with at most :data:`TUNING_ADDED_LAG` frames of added lag on seed :data:`SEED`; among
rows within :data:`TIE` of it, the one furthest from both failure modes: added lag
against the target, and the still hand's largest filtered speed against the dead band,
since real footage is noisier than our renders), and the JSON says whether the shipped
defaults are its choice. The defaults are then checked on pairs of sequences rendered with other
seeds (:data:`HELD_OUT_SEEDS`), on the pairs of :data:`FLESH_SEEDS` drawn with the
independent flesh appearance (docs/appearance.md), and on seed :data:`SEED` filmed at
:data:`FAST_RATE_FACTOR` times the frame rate in both appearances, none of which took part
in choosing them.
"""

from __future__ import annotations

import itertools
import time
from dataclasses import replace
from typing import Any

import numpy as np

from digiteyes.benchmarks._machine import emit, machine_info, machine_lines
from digiteyes.benchmarks.tracker import SEED, render_sequence, track_sequence
from digiteyes.filters import OneEuroOptions, one_euro_filter, one_euro_trace
from digiteyes.kinematics import KinematicModel, forward_kinematics, resample_states
from digiteyes.kinematics.joint_angles import joint_angles_deg
from digiteyes.kinematics.keypoints import keypoints
from digiteyes.synth.scenarios import build_scenario
from digiteyes.trackers import FeatureTrackerOptions

WARM_UP = 5
"""Frames left out at the start of each sequence (the tracker and filter settling)."""
LAG_STEP = 0.05
MAX_LAG = 4.0
MIN_CUTOFFS = (0.1, 0.2, 0.5, 1.0)
BETAS_PER_MM_S = (0.0, 0.05, 0.1, 0.2, 0.3, 0.5)
D_CUTOFFS = (0.2, 0.5, 1.0)
DEADBANDS_MM_S = (0.0, 5.0, 10.0, 15.0, 20.0)
SLOW_FACTORS = (1, 2, 4, 8)
"""How many times slower than ``whole-hand`` the slow-motion check plays it."""
SLOW_FRAMES = 400
"""Frames of each slowed sequence, at most."""
FAST_RATE_FACTOR = 3
"""The held-out check at another frame rate films ``whole-hand`` this many times faster
(30 frames/s: the same motion, a third of the motion per frame)."""
APPEARANCES = ("model", "flesh")
TIE = 0.01
"""Relative jitter-ratio difference under which :func:`choose` treats rows as tied."""
HELD_OUT_SEEDS = (SEED + 1, SEED + 2)
"""Seeds of the pairs of sequences on which the defaults are checked (not tuned), in our
drawing; the flesh hand is checked on the five seeds of :data:`FLESH_SEEDS`."""
FLESH_SEEDS = tuple(range(SEED, SEED + 5))
TARGET_JITTER_RATIO = 5.0
TARGET_ADDED_LAG = 1.0
TUNING_ADDED_LAG = 0.8
"""Added lag allowed when choosing the defaults on seed :data:`SEED`: a margin under
:data:`TARGET_ADDED_LAG` for sequences the choice has not seen."""


def keypoint_tracks(model: KinematicModel, states: np.ndarray) -> np.ndarray:
    """Keypoints (T, K, 3), world mm, of states (T, n_q)."""
    return keypoints(model, forward_kinematics(model, states))[1]


def jitter(model: KinematicModel, states: np.ndarray) -> dict[str, float]:
    """RMS frame-to-frame keypoint displacement (mm) and joint-angle change (degrees)."""
    points = keypoint_tracks(model, states[WARM_UP:])
    _, angles = joint_angles_deg(model, states[WARM_UP:])
    step = np.linalg.norm(np.diff(points, axis=0), axis=-1)
    return {"keypoint_mm": float(np.sqrt(np.mean(step ** 2))),
            "joint_angle_deg": float(np.sqrt(np.mean(np.diff(angles, axis=0) ** 2)))}


def lag_frames(estimate_kp: np.ndarray, truth_kp: np.ndarray,
               max_lag: float = MAX_LAG) -> tuple[float, float]:
    """The shift ``s`` in frames (0 to ``max_lag``) minimising the RMS of
    ``estimate[t] - truth(t - s)``, and that RMS (mm); frames whose shifted truth falls
    outside the sequence are left out."""
    n = len(truth_kp)
    t = np.arange(WARM_UP + int(np.ceil(max_lag)), n)
    best = (0.0, np.inf)
    for s in np.arange(0.0, max_lag + 1e-9, LAG_STEP):
        u = t - s
        lo = np.floor(u).astype(int)
        w = (u - lo)[:, None, None]
        shifted = (1.0 - w) * truth_kp[lo] + w * truth_kp[np.minimum(lo + 1, n - 1)]
        rms = float(np.sqrt(np.mean(np.sum((estimate_kp[t] - shifted) ** 2, axis=-1))))
        if rms < best[1]:
            best = (float(s), rms)
    return best


def mean_error_mm(estimate_kp: np.ndarray, truth_kp: np.ndarray) -> float:
    """Mean keypoint error (mm) after the warm-up."""
    return float(np.linalg.norm(estimate_kp[WARM_UP:] - truth_kp[WARM_UP:], axis=-1).mean())


def assess(model: KinematicModel, still: np.ndarray, still_truth_kp: np.ndarray,
           moving: np.ndarray, moving_truth_kp: np.ndarray) -> dict[str, Any]:
    """Jitter, lag and error of one pair of estimated sequences (raw or filtered)."""
    moving_kp = keypoint_tracks(model, moving)
    lag, lag_rms = lag_frames(moving_kp, moving_truth_kp)
    return {"jitter_still": jitter(model, still), "lag_frames": lag,
            "rms_at_lag_mm": lag_rms,
            "error_still_mm": mean_error_mm(keypoint_tracks(model, still), still_truth_kp),
            "error_moving_mm": mean_error_mm(moving_kp, moving_truth_kp),
            "jitter_moving": jitter(model, moving)}


def tracked_pair(seed: int, n_still: int, n_moving: int, progress: bool,
                 appearance: str = "model", rate_factor: int = 1) -> dict[str, Any]:
    """Render (in ``appearance``, docs/appearance.md) and track the still and moving hands
    of ``whole-hand`` with ``seed``: the model, fps, the estimated states and the true
    keypoints of both, and the moving hand's true states. ``rate_factor`` films the same
    motion at that many times the scenario's frame rate (states interpolated on the
    manifold, :func:`~digiteyes.kinematics.resample_states`; both sequences get that many
    times more frames)."""
    moving = build_scenario("whole-hand", seed=seed, n_frames=n_moving)
    states = moving.states[:n_moving]
    if rate_factor > 1:
        states = resample_states(moving.model, states, 1.0 / rate_factor)
    moving = replace(moving, states=states, fps=moving.fps * rate_factor)
    still = replace(moving, name="still",
                    states=np.repeat(states[:1], n_still * rate_factor, axis=0))
    pair: dict[str, Any] = {"model": moving.model, "fps": moving.fps,
                            "moving_truth_states": moving.states}
    for name, scenario in (("still", still), ("moving", moving)):
        sequence = render_sequence(scenario, seed=seed, progress=progress,
                                   appearance=appearance)
        pair[name] = track_sequence(sequence, FeatureTrackerOptions(), label=name,
                                    progress=progress).log.states
        pair[f"{name}_truth"] = keypoint_tracks(moving.model, scenario.states)
    return pair


def slow_motion(model: KinematicModel, states: np.ndarray, fps: float,
                options: OneEuroOptions) -> list[dict[str, float]]:
    """The filter on noise-free ``states`` slowed by each of :data:`SLOW_FACTORS`: RMS
    keypoint speed (median, mm/s), lag (frames) and keypoint error (mean, largest; mm)."""
    rows = []
    for factor in SLOW_FACTORS:
        truth = resample_states(model, states, 1.0 / factor)[:SLOW_FRAMES]
        truth_kp = keypoint_tracks(model, truth)
        filtered_kp = keypoint_tracks(model, one_euro_filter(model, truth, fps, options))
        speed = fps * np.sqrt(np.mean(np.sum(np.diff(truth_kp, axis=0) ** 2, axis=-1),
                                      axis=1))
        error = np.linalg.norm(filtered_kp - truth_kp, axis=-1).mean(axis=1)
        rows.append({"factor": factor, "speed_mm_s_median": float(np.median(speed)),
                     "lag_frames": lag_frames(filtered_kp, truth_kp,
                                              max_lag=MAX_LAG * factor)[0],
                     "error_mm_mean": float(error.mean()), "error_mm_max": float(error.max())})
    return rows


def grid_options() -> list[OneEuroOptions]:
    """The settings of the grid, in table order."""
    return [OneEuroOptions(min_cutoff_hz=cutoff, beta_per_mm_s=beta, d_cutoff_hz=d_cutoff,
                           deadband_mm_s=band)
            for band, cutoff, beta, d_cutoff in itertools.product(
                DEADBANDS_MM_S, MIN_CUTOFFS, BETAS_PER_MM_S, D_CUTOFFS)]


def choose(grid: list[dict[str, Any]]) -> dict[str, Any] | None:
    """The rule that chose the defaults: among the grid rows with at most
    :data:`TUNING_ADDED_LAG` frames of added lag, those within :data:`TIE` of the largest
    jitter ratio; of these, the one with the largest smaller margin, where the lag margin
    is ``1 - added_lag / TARGET_ADDED_LAG`` and the noise margin ``1 - peak / deadband``
    (``peak``: the still hand's largest filtered keypoint speed). None when no row
    qualifies."""
    allowed = [row for row in grid if row["added_lag_frames"] <= TUNING_ADDED_LAG + 1e-9]
    if not allowed:
        return None
    best = max(row["jitter_ratio"] for row in allowed)
    tied = [row for row in allowed if row["jitter_ratio"] >= best * (1.0 - TIE)]
    return max(tied, key=_margin)


def _margin(row: dict[str, Any]) -> float:
    """The smaller of a grid row's lag and noise margins (see :func:`choose`)."""
    lag = 1.0 - row["added_lag_frames"] / TARGET_ADDED_LAG
    band = row["deadband_mm_s"]
    noise = 1.0 - row["filtered"]["still_peak_speed_mm_s"] / band if band > 0 else -np.inf
    return min(lag, noise)


def run(json_path: str | None = None, quick: bool = False, *, progress: bool = True) -> dict:
    """Track the still and moving hands, filter with a grid of settings and with the
    defaults, print the table and optionally write JSON (see the module docstring)."""
    started = time.perf_counter()
    n_still, n_moving = (30, 80) if quick else (80, 200)
    pair = tracked_pair(SEED, n_still, n_moving, progress)
    model, fps = pair["model"], pair["fps"]

    def evaluate(options: OneEuroOptions | None, pair: dict[str, Any] = pair) -> dict[str, Any]:
        still, moving = pair["still"], pair["moving"]
        peak = None
        if options is not None:
            trace = one_euro_trace(model, still, fps, options)
            still, peak = trace.states, float(trace.speed_mm_s[WARM_UP:].max())
            moving = one_euro_filter(model, moving, fps, options)
        return {**assess(model, still, pair["still_truth"], moving, pair["moving_truth"]),
                "still_peak_speed_mm_s": peak}

    raw = evaluate(None)
    grid = [{**vars(options), **_versus(raw, evaluate(options))} for options in grid_options()]
    defaults = OneEuroOptions()
    chosen = choose(grid)
    held_out = []
    for seed, appearance, factor in ([(s, "model", 1) for s in HELD_OUT_SEEDS]
                                     + [(s, "flesh", 1) for s in FLESH_SEEDS]
                                     + [(SEED, a, FAST_RATE_FACTOR) for a in APPEARANCES]):
        other = tracked_pair(seed, n_still, n_moving, progress, appearance, factor)
        other_raw = evaluate(None, other)
        versus = _versus(other_raw, evaluate(defaults, other))
        held_out.append({"seed": seed, "appearance": appearance, "fps": other["fps"],
                         "raw": other_raw, **versus,
                         "added_lag_ms": 1000.0 * versus["added_lag_frames"] / other["fps"]})
    tuned = _versus(raw, evaluate(defaults))
    result: dict[str, Any] = {
        "benchmark": "smoothing", "quick": quick, "machine": machine_info(),
        "settings": {"seed": SEED, "held_out_seeds": list(HELD_OUT_SEEDS),
                     "flesh_seeds": list(FLESH_SEEDS), "fps": fps,
                     "still_frames": n_still,
                     "moving_frames": n_moving, "warm_up": WARM_UP, "lag_step": LAG_STEP,
                     "tuning_added_lag_frames": TUNING_ADDED_LAG,
                     "targets": {"jitter_ratio": TARGET_JITTER_RATIO,
                                 "added_lag_frames": TARGET_ADDED_LAG}},
        "raw": raw,
        "defaults": {"options": vars(defaults), **tuned,
                     "chosen_by_rule": chosen is not None and all(
                         chosen[key] == value for key, value in vars(defaults).items())},
        "held_out": held_out,
        "meets_targets_everywhere": bool(tuned["meets_targets"] and all(
            entry["meets_targets"] for entry in held_out if entry["fps"] == fps)),
        "slow_motion": slow_motion(model, pair["moving_truth_states"], fps, defaults),
        "grid": grid,
    }
    result["wall_seconds"] = time.perf_counter() - started
    return emit(result, format_table(result), json_path)


def _versus(raw: dict[str, Any], filtered: dict[str, Any]) -> dict[str, Any]:
    ratio = raw["jitter_still"]["keypoint_mm"] / max(filtered["jitter_still"]["keypoint_mm"],
                                                     1e-12)
    added = filtered["lag_frames"] - raw["lag_frames"]
    return {"filtered": filtered, "jitter_ratio": ratio, "added_lag_frames": added,
            "meets_targets": bool(ratio >= TARGET_JITTER_RATIO
                                  and added <= TARGET_ADDED_LAG + 1e-9)}


def _row(label: str, entry: dict[str, Any]) -> str:
    f = entry["filtered"]
    mark = "yes" if entry["meets_targets"] else "no"
    return (f"{label:<42} {f['jitter_still']['keypoint_mm']:>8.3f} {entry['jitter_ratio']:>6.1f}x"
            f" {f['lag_frames']:>6.2f} {entry['added_lag_frames']:>+6.2f}"
            f" {f['error_still_mm']:>7.2f} {f['error_moving_mm']:>7.2f}  {mark}")


def format_table(result: dict[str, Any]) -> str:
    """The table of :func:`run`: raw, the defaults, then the grid."""
    raw = result["raw"]
    s = result["settings"]
    lines = [f"smoothing benchmark{' (quick)' if result['quick'] else ''}",
             *machine_lines(result["machine"]),
             f"still hand {s['still_frames']} frames, whole-hand {s['moving_frames']} frames at "
             f"{s['fps']:g} frames/s; targets: jitter down {TARGET_JITTER_RATIO:g}x, added lag "
             f"<= {TARGET_ADDED_LAG:g} frame", "",
             f"{'settings':<42} {'jitter':>8} {'ratio':>7} {'lag':>6} {'added':>6}"
             f" {'err st':>7} {'err mv':>7}  targets",
             f"{'':<42} {'mm/frm':>8} {'':>7} {'frames':>6} {'frames':>6} {'mm':>7} {'mm':>7}",
             f"{'raw tracker':<42} {raw['jitter_still']['keypoint_mm']:>8.3f} {'1.0x':>7}"
             f" {raw['lag_frames']:>6.2f} {'':>6} {raw['error_still_mm']:>7.2f}"
             f" {raw['error_moving_mm']:>7.2f}",
             _row("defaults", result["defaults"]),
             *(_row(f"defaults, seed {entry['seed']} {entry['appearance']}, "
                    f"{entry['fps']:g}/s (held out)", entry)
               for entry in result["held_out"]),
             "defaults chosen by the tuning rule: "
             f"{'yes' if result['defaults']['chosen_by_rule'] else 'no'}; targets met on "
             f"every pair at the scenario's {s['fps']:g} frames/s: "
             f"{'yes' if result['meets_targets_everywhere'] else 'no'}",
             *(f"at {e['fps']:g} frames/s ({e['appearance']}) the added lag is "
               f"{e['added_lag_ms']:.0f} ms ({e['added_lag_frames']:.2f} frames)"
               for e in result["held_out"] if e["fps"] != s["fps"]), "",
             "defaults on the true whole-hand motion slowed down (no tracker):",
             *(f"  {row['factor']}x slower: keypoint speed {row['speed_mm_s_median']:.1f} mm/s,"
               f" lag {row['lag_frames']:.2f} frames, error {row['error_mm_mean']:.2f} mm"
               f" mean, {row['error_mm_max']:.2f} mm largest"
               for row in result["slow_motion"]), ""]
    for entry in result["grid"]:
        label = (f"fc {entry['min_cutoff_hz']:g}, beta {entry['beta_per_mm_s']:g}, "
                 f"dc {entry['d_cutoff_hz']:g}, band {entry['deadband_mm_s']:g}")
        lines.append(_row(label, entry))
    return "\n".join(lines)
