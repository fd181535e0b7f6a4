"""Loss-flag benchmark over a textured backdrop: the silhouette rule's colour model.

The accuracy benchmark (:mod:`digiteyes.benchmarks.accuracy`) renders grey images over
black cloth, where the silhouette loss rule works from a grey threshold. Over clutter no
threshold separates the hand, and before the colour model
(:mod:`digiteyes.features.colour_foreground`) the rule stayed off there: a track that had
left the hand was flagged only by the trackers' residual rules, which rarely notice. This
suite renders the hand in colour over the ``clutter`` backdrop (random coloured shapes,
some of them skin-coloured), in both appearances (:data:`APPEARANCES`: the independent
flesh hand beside our own drawing), for the camera setups of the accuracy table,
tracks each from its true first state with :data:`TRACKERS`, once with the colour model
off and once on (``colour_foreground``), and scores the loss flag against the truth
(:mod:`digiteyes.evaluate.truth_loss`: a frame is truly lost when its mean fingertip
error exceeds 30 mm or a fingertip 50 mm). The tracks are the same both ways (the flag
does not move the estimate of these trackers, unless a finger search is switched on);
only the flag differs. Per setup it also reports how the colour model split the first
frame of each camera (hand pixels it keeps, backdrop pixels it takes for hand) and
whether it was accepted.

Run it with ``digiteyes bench clutter-flag [--json FILE] [--quick]``; docs/accuracy.md
explains the result.
"""

from __future__ import annotations

import time
from dataclasses import replace
from typing import Any

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
from digiteyes.features.colour_foreground import ColourForeground
from digiteyes.features.foreground import Foreground
from digiteyes.features.slices import prepare_image
from digiteyes.trackers import tracker_entry
from digiteyes.trackers.silhouette_loss import SilhouetteLoss

TRACKERS = ("features", "templates", "divide-conquer")
"""The trackers of the seeds with a silhouette rule and no learned detector."""
FRAMES = 60
"""Frames per sequence (the index finger's whole curl and more)."""
QUICK_FRAMES = 4


def colour_fits(sequence: Any) -> list[dict[str, Any]]:
    """How the silhouette rule splits each camera's first frame at the true first state:
    whether the grey threshold fits (a plain backdrop), else the colour model's figures
    (None when the model was refused)."""
    start = sequence.scenario.initial_state
    rule = SilhouetteLoss(sequence.scenario.model, sequence.rig)
    first = sequence.images[0]
    rule.check([prepare_image(image) for image in first], start, start, colours=first)
    return [{"camera": camera.name, "grey_threshold": isinstance(fg, Foreground),
             "colour_model": {"hand_recall": fg.hand_recall,
                              "backdrop_share": fg.backdrop_share}
             if isinstance(fg, ColourForeground) else None}
            for camera, fg in zip(sequence.rig, rule.foreground, strict=True)]


def measure(frames: int) -> list[dict[str, Any]]:
    """Every setup of the accuracy table, rendered in colour over clutter in each
    appearance, tracked by every tracker of :data:`TRACKERS` with the colour model off and
    on (one thread)."""
    rows = []
    with _one_thread():
        for appearance, source in ((a, s) for a in APPEARANCES
                                   for s in dict.fromkeys(s for s, _ in SETUPS.values())):
            rendered = render_sequence(scenario_for(source, "exact", frames),
                                       background="clutter", appearance=appearance,
                                       color=True)
            for label, (setup_source, cameras) in SETUPS.items():
                if setup_source != source:
                    continue
                sequence = rendered.cameras(cameras)
                fits = colour_fits(sequence)
                for name in TRACKERS:
                    for colour in (False, True):
                        options = replace(tracker_entry(name).options_type(),
                                          colour_foreground=colour)
                        outcome = track_sequence(sequence, options, f"{name} {label}",
                                                 tracker=name)
                        figures = row_figures(sequence, outcome)
                        rows.append({"tracker": name, "appearance": appearance,
                                     "setup": label, "colour_model": colour,
                                     "cameras": fits} | {
                            k: figures[k] for k in ("fingertip_err_mm_mean",
                                                    "truly_lost_frames", "lost_frames",
                                                    "flag", "frames")})
    return rows


def totals(rows: list[dict[str, Any]]) -> dict[str, Any]:
    """Per tracker, appearance and colour setting, the flag's confusion counts summed over
    the setups, with precision and recall (:func:`~digiteyes.benchmarks.accuracy.
    flag_totals`)."""
    groups: dict[str, list[dict[str, Any]]] = {}
    for row in rows:
        key = (f"{row['tracker']} {row['appearance']} colour "
               f"{'on' if row['colour_model'] else 'off'}")
        groups.setdefault(key, []).append(row)
    return {key: flag_totals(group) for key, group in groups.items()}


def run(json_path: str | None = None, quick: bool = False) -> dict:
    """Measure (:func:`measure`), print the table, write JSON to ``json_path``."""
    started = time.perf_counter()
    frames = QUICK_FRAMES if quick else FRAMES
    rows = measure(frames)
    result = {"benchmark": "clutter-flag", "quick": quick, "machine": machine_info(),
              "settings": {"frames": frames, "trackers": list(TRACKERS),
                           "appearances": list(APPEARANCES), "background": "clutter",
                           "color": True},
              "rows": rows, "totals": totals(rows)}
    result["wall_seconds"] = time.perf_counter() - started
    return emit(result, format_table(result), json_path)


def format_table(result: dict[str, Any]) -> str:
    """One line per tracker and setup (flag without | with the colour model), the colour
    model's first-frame split per camera, and the totals."""
    lines = [f"clutter-flag benchmark{' (quick)' if result['quick'] else ''}",
             *machine_lines(result["machine"]),
             f"the hand in colour over clutter, {result['settings']['frames']} frames, "
             "true first state; flag: flagged frames, precision / recall against the truth",
             "", f"{'tracker':<16} {'appearance':<10} {'setup':<16} {'tip mm':>7} "
                 f"{'truly lost':>10} "
                 f"{'flag, colour off':>22} {'flag, colour on':>22}  colour model per camera "
                 "(hand kept / backdrop taken)"]
    rows = result["rows"]
    for off, on in zip(rows[0::2], rows[1::2], strict=True):
        cams = ", ".join("grey" if c["grey_threshold"] else "refused" if c["colour_model"] is
                         None else f"{100 * c['colour_model']['hand_recall']:.0f}% / "
                         f"{100 * c['colour_model']['backdrop_share']:.1f}%"
                         for c in on["cameras"])
        cells = [f"{r['lost_frames']:>3} {precision_recall(r['flag']):>12}" for r in (off, on)]
        lines.append(f"{on['tracker']:<16} {on['appearance']:<10} {on['setup']:<16} "
                     f"{on['fingertip_err_mm_mean']:>7.1f} {on['truly_lost_frames']:>10} "
                     f"{cells[0]:>22} {cells[1]:>22}  {cams}")
    lines += ["", "totals over the setups (precision / recall):"]
    lines += [f"  {key:<38} {precision_recall(t)}  "
              f"(TP {t['true_positive']}, FP {t['false_positive']}, FN {t['false_negative']})"
              for key, t in result["totals"].items()]
    return "\n".join(lines)
