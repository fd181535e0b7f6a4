"""Accuracy and loss flag on renders the trackers were not developed on.

The accuracy benchmark (:mod:`digiteyes.benchmarks.accuracy`) draws a well-lit, light
hand over black cloth with a quiet sensor, the thesis's setting. A user's camera is
noisier, their skin may be darker, the light may come from the side, the wall behind them
grey. This suite renders the camera setups of the accuracy table (the exact hand, both
appearances: the independent flesh hand beside our own drawing) under each of
:data:`VARIANTS`, tracks each from its true first state with :data:`TRACKERS` (and,
with the MediaPipe extra, :data:`DETECTOR_TRACKERS`) at their defaults, and reports per
variant and tracker the mean fingertip error, the frames truly
lost (:mod:`digiteyes.evaluate.truth_loss`) and the loss flag's precision and recall.
Each variant changes one thing against ``baseline`` (the accuracy table's own renders).

Run it with ``digiteyes bench render-variants [--json FILE] [--quick]``;
docs/accuracy.md discusses the result.
"""

from __future__ import annotations

import time
from itertools import product
from typing import Any

import numpy as np
from tqdm import tqdm

from digiteyes.benchmarks._machine import emit, machine_info, machine_lines
from digiteyes.benchmarks.accuracy import (
    APPEARANCES,
    SETUPS,
    flag_totals,
    precision_recall,
    row_figures,
    scenario_for,
)
from digiteyes.benchmarks.tracker import _one_thread, render_sequence, track_sequence
from digiteyes.detect.mediapipe_detector import mediapipe_available
from digiteyes.trackers import tracker_entry

VARIANTS: dict[str, dict[str, Any]] = {
    "baseline": {},
    "sensor noise 8": {"noise_sigma": 8.0},
    "blur 1.5 px": {"blur_sigma": 1.5},
    "dark skin": {"skin_tone": "dark"},
    "side light, shadows": {"light_dir": (-1.0, 0.3, 0.4), "shadows": True},
    "grey wall": {"background": "uniform", "background_level": 0.45},
}
"""Label -> :class:`~digiteyes.synth.RenderOptions` fields changed against the accuracy
table's renders (grey, black cloth, sensor noise 2 grey levels, the renderer's default
light, skin albedo 0.85)."""
TRACKERS = ("features", "templates", "divide-conquer")
"""The seeds' trackers (no learned detector: their images are the renders alone)."""
DETECTOR_TRACKERS = ("features+keypoints",)
"""Measured too where the MediaPipe extra is installed: what ``track --tracker auto`` runs
on a dataset whose hand MediaPipe sees."""
FRAMES = 60
QUICK_FRAMES = 4


def trackers() -> tuple[str, ...]:
    """:data:`TRACKERS`, and :data:`DETECTOR_TRACKERS` when MediaPipe is installed."""
    return TRACKERS + (DETECTOR_TRACKERS if mediapipe_available() else ())


def measure(frames: int) -> list[dict[str, Any]]:
    """Every variant, appearance and setup tracked by every tracker (one thread)."""
    rows = []
    sources = dict.fromkeys(source for source, _ in SETUPS.values())
    jobs = list(product(VARIANTS.items(), APPEARANCES, sources))
    with _one_thread():
        for (variant, render), appearance, source in tqdm(
                jobs, desc="render-variants", unit="sequence", leave=False):
            rendered = render_sequence(scenario_for(source, "exact", frames),
                                       appearance=appearance, render=render)
            for label, (setup_source, cameras) in SETUPS.items():
                if setup_source != source:
                    continue
                sequence = rendered.cameras(cameras)
                for name in trackers():
                    outcome = track_sequence(sequence, tracker_entry(name).options_type(),
                                             f"{name} {label}", tracker=name)
                    figures = row_figures(sequence, outcome)
                    rows.append({"variant": variant, "tracker": name,
                                 "appearance": appearance, "setup": label} | {
                        k: figures[k] for k in ("fingertip_err_mm_mean", "truly_lost_frames",
                                                "lost_frames", "flag", "frames")})
    return rows


def totals(rows: list[dict[str, Any]]) -> dict[str, dict[str, Any]]:
    """Per ``"variant | tracker | appearance"``: the mean over the setups of the mean
    fingertip error (mm), the truly lost frames summed, and the flag's confusion counts
    with precision and recall (:func:`~digiteyes.benchmarks.accuracy.flag_totals`)."""
    groups: dict[str, list[dict[str, Any]]] = {}
    for row in rows:
        groups.setdefault(f"{row['variant']} | {row['tracker']} | {row['appearance']}",
                          []).append(row)
    return {key: {"fingertip_err_mm_mean": float(np.mean(
                      [r["fingertip_err_mm_mean"] for r in group])),
                  "truly_lost_frames": int(sum(r["truly_lost_frames"] for r in group)),
                  "frames": int(sum(r["frames"] for r in group)),
                  "flag": flag_totals(group)}
            for key, group in groups.items()}


def run(json_path: str | None = None, quick: bool = False) -> dict:
    """Measure (:func:`measure`), print the table, write JSON to ``json_path``."""
    started = time.perf_counter()
    frames = QUICK_FRAMES if quick else FRAMES
    rows = measure(frames)
    result = {"benchmark": "render-variants", "quick": quick, "machine": machine_info(),
              "settings": {"frames": frames, "trackers": list(trackers()),
                           "appearances": list(APPEARANCES), "hand": "exact",
                           "variants": {k: {f: list(v) if isinstance(v, tuple) else v
                                            for f, v in fields.items()}
                                        for k, fields in VARIANTS.items()}},
              "rows": rows, "totals": totals(rows)}
    result["wall_seconds"] = time.perf_counter() - started
    return emit(result, format_table(result), json_path)


def format_table(result: dict[str, Any]) -> str:
    """One line per variant and tracker: own drawing | flesh hand side by side."""
    frames, n_setups = result["settings"]["frames"], len(SETUPS)
    lines = [f"render-variants benchmark{' (quick)' if result['quick'] else ''}",
             *machine_lines(result["machine"]),
             f"exact hand, {n_setups} camera setups of the accuracy table, {frames} frames "
             "each, true first state; own drawing | flesh hand",
             "", f"{'variant':<20} {'tracker':<15} {'tip mm, mean of setups':>24} "
                 f"{'truly lost':>12} {'flag precision / recall':>30}"]
    t = result["totals"]
    for variant in result["settings"]["variants"]:
        for name in result["settings"]["trackers"]:
            own, flesh = (t.get(f"{variant} | {name} | {a}") for a in ("model", "flesh"))
            if own is None or flesh is None:
                continue
            tips = f"{own['fingertip_err_mm_mean']:.1f} | {flesh['fingertip_err_mm_mean']:.1f}"
            lost = f"{own['truly_lost_frames']} | {flesh['truly_lost_frames']}"
            flag = " | ".join(precision_recall(x["flag"]) for x in (own, flesh))
            lines.append(f"{variant:<20} {name:<15} {tips:>24} {lost:>12} {flag:>30}")
    return "\n".join(lines)
