"""Layered template benchmark: accuracy and speed of the template trackers on the
synthetic scenarios, and agreement of the predicted visibility orders with the renderer.

Each scenario is tracked with the templates alone and (except ``natural`` with one
camera) with templates plus edge features, in both appearances of the renderer: the
tracking model's own drawing (``model``) and the independent flesh hand (``flesh``,
docs/appearance.md), side by side.

* ``two-finger-occlusion`` (thesis Sec. 4.4.2, one camera, 80 frames): largest deviation
  of the middle finger's joints from the truth (rad; target 0.03), index joint-angle RMS
  (deg; target 3), mean fingertip error (mm; target 3), lost frames (target 0); also with
  the background template of Sec. 4.4.2 (``background="filtered"``, off by default: it
  pins the palm's depth but costs the index's joints and four fifths of the speed;
  docs/templates.md);
* ``natural`` (Huang et al., 200 frames): mean fingertip error with two cameras (target
  8 mm) and one (15 mm), lost frames; with the silhouette finger search on
  (``finger_search``, off by default: it costs the loss flag its recall on the desk rows
  of ``bench accuracy``; docs/templates.md) with two cameras and, for
  ``templates+features``, one;
* the template refresh is gated by each part's turn with one camera by default
  (``TemplateOptions.refresh_turn_deg``, ``refresh_turn_cameras``; docs/templates.md,
  "Refresh and drift"): both trackers also run ``two-finger-occlusion`` with the gate off
  (``ungated``) and ``natural`` with two cameras with the gate on (``+gated``), the
  settings it was chosen against;
* the joints' links are ordered pixel by pixel with two cameras by default
  (``TemplateOptions.pixel_depth_at_joints``; docs/templates.md): both trackers also run
  ``natural`` with two cameras by the joint rule alone (``joint rule``), and ``templates``
  runs ``two-finger-occlusion`` with the pixel order on (``+pixel depth``), the settings
  the default was chosen against;
* a hidden template pixel costs ``HIDDEN_RESIDUAL_RIG`` with two cameras by default
  (``TemplateOptions.hidden_residual``; docs/templates.md, "What hiding costs"): both
  trackers also run ``natural`` with two cameras with hiding free (``free hiding``, the
  thesis's error), and ``templates`` runs ``two-finger-occlusion`` with the cost
  (``+hiding cost``);
* the desk pair of ``bench accuracy`` (issue 14's third target: no frame whose mean
  fingertip error exceeds 30 mm, two cameras, the hand of the model's size and one 0.9x
  its size): both trackers at their defaults and with the curl search
  (:data:`CURL_SEARCH`: the silhouette rule's open-digit test for every digit,
  ``judge_curled_digits``, and the finger search of the digits the rule names,
  ``named_finger_search``; off by default: it costs the loss flag its precision on
  those rows, docs/templates.md), with the worst frame, the frames above 30 mm and the
  loss flag's precision and recall; one render per hand, the noise of ``bench
  accuracy``; the curl search also on ``natural`` with one and two cameras;
* every run is made on :data:`SEEDS` renders that differ in their sensor noise
  (:data:`~digiteyes.benchmarks.tracker.NOISE_SIGMA` grey levels): a track that passes near
  a decision (a finger that can flip) ends differently with another draw of the noise, so
  a row reports the mean over the seeds with each seed's figures beside it;
* truly lost frames (:func:`~digiteyes.evaluate.truth_loss.truth_loss`: mean fingertip
  error above 30 mm or one tip above 50 mm) beside the frames the tracker flagged;
* speed: frames per second of ``step`` (rendering excluded, the first frame with the
  template acquisition and compilation excluded) and milliseconds per iteration split
  into visibility, template rendering (placing template pixels), residual (the compiled
  pass), Jacobian (chaining into ``H``, ``g``), edge features (combined tracker) and
  solve;
* visibility: share of contested pixels where the predicted front part is the one the
  renderer's depth buffer shows, over random states, and the time to predict an order.

OpenCV and numba are held to one thread. ``digiteyes bench templates [--json FILE]
[--quick]`` (``--quick``: fewer frames and states, one seed).
"""

from __future__ import annotations

import time
from dataclasses import asdict, fields, replace

import numpy as np

from digiteyes.benchmarks._machine import emit, kernel_threads, machine_info, machine_lines
from digiteyes.benchmarks.accuracy import HANDS, row_figures, scenario_for
from digiteyes.benchmarks.tracker import NOISE_SIGMA, render_sequence, track_sequence
from digiteyes.camera import Rig
from digiteyes.evaluate.truth_loss import truth_loss
from digiteyes.kinematics import forward_kinematics
from digiteyes.occlusion.agreement import order_agreement
from digiteyes.occlusion.parts import facing_plane, template_parts
from digiteyes.occlusion.visibility import predict_visibility
from digiteyes.occlusion.windows import image_windows
from digiteyes.pipeline import step_frames
from digiteyes.synth import RenderOptions, render_views
from digiteyes.synth.options import APPEARANCES
from digiteyes.synth.scenarios import build_scenario
from digiteyes.templates.layered import HIDDEN_RESIDUAL_RIG, TemplateOptions
from digiteyes.trackers import LayeredTemplateOptions, create_tracker

STAGES = ("visibility", "template_rendering", "residual", "jacobian", "features",
          "linear_solve")
SEEDS = (0, 1, 2)
"""Noise seeds of the full run (``--quick``: the first)."""
_SEED_STRIDE = 100_000
"""Frame ``i`` of seed ``s`` is rendered with the noise seed ``i + s * _SEED_STRIDE``."""
CURL_SEARCH = {"named_finger_search": True, "judge_curled_digits": True}
"""The options of the desk rows' curl search (``--option KEY=true`` for each)."""
DESK_FRAMES = 120
"""Frames of the desk pair (``bench accuracy``'s; ``--quick``: 20)."""
_AVERAGED = ("mean_tip_error_mm", "max_frame_tip_error_mm", "lost_frames",
             "truly_lost_frames", "frames_per_second", "index_joint_rms_deg",
             "middle_max_deviation_rad")


def track_scenario(name: str, n_cameras: int, n_frames: int | None,
                   options: LayeredTemplateOptions, tracker: str = "templates",
                   appearance: str = "model", seed: int = 0) -> dict:
    """Render a scenario in ``appearance`` (:data:`~digiteyes.synth.options.APPEARANCES`)
    with the sensor noise of ``seed``, track it from its first true state with the
    registered ``tracker`` (created by :func:`~digiteyes.trackers.create_tracker`, stepped
    by the run loop :func:`~digiteyes.pipeline.step_frames`) and score it against the
    truth (figures of the module docstring)."""
    scenario = build_scenario(name, n_frames=n_frames)
    model = scenario.model
    rig = Rig(scenario.rig.cameras[:n_cameras])
    render = RenderOptions(appearance=appearance, noise_sigma=NOISE_SIGMA)
    frames = [[v.image for v in render_views(model, q, rig, render,
                                             rng=i + seed * _SEED_STRIDE)]
              for i, q in enumerate(scenario.states)]
    settings = {f.name: getattr(options, f.name) for f in fields(options)}
    runner = create_tracker(tracker, model, rig, **settings)
    states, lost, seconds = [], 0, 0.0
    stage_seconds = dict.fromkeys(STAGES, 0.0)
    iterations = 0
    for i, _, result, _ in step_frames(runner, frames, scenario.initial_state):
        states.append(result.state)
        lost += bool(result.lost)
        if i > 0:
            seconds += result.timings["total"]
            iterations += result.iterations
            for stage in STAGES:
                stage_seconds[stage] += result.timings[stage]
    est = np.array(states)
    truth = scenario.states
    rig_templates = options.templates.for_rig(n_cameras)
    tips = [link.row for link in model.links if link.kind == "tip"]
    kt = forward_kinematics(model, truth).T_world_shape[:, tips][..., :3, 3]
    ke = forward_kinematics(model, est).T_world_shape[:, tips][..., :3, 3]
    tip_error = np.linalg.norm(kt - ke, axis=2)  # (frames, tips)
    per_frame = tip_error.mean(axis=1)
    out = {"scenario": name, "tracker": tracker, "appearance": appearance,
           "cameras": n_cameras, "seed": seed, "finger_search": options.finger_search,
           "curl_search": all(getattr(options, k) == v for k, v in CURL_SEARCH.items()),
           "background": options.background,
           "refresh_gated": rig_templates.refresh_turn_deg is not None,
           "pixel_depth_at_joints": rig_templates.pixel_depth_at_joints,
           "hiding_costs": rig_templates.hidden_residual > 0,
           "frames": len(truth),
           "iterations_per_frame": options.iterations_per_frame,
           "mean_tip_error_mm": float(tip_error.mean()),
           "max_frame_tip_error_mm": float(per_frame.max()),
           "tip_error_per_frame_mm": [round(float(e), 2) for e in per_frame],
           "lost_frames": int(lost),
           "truly_lost_frames": int(truth_loss(model, est, truth).lost.sum()),
           "frames_per_second": (len(truth) - 1) / seconds if seconds else None,
           "ms_per_iteration": {s: 1e3 * v / max(iterations, 1)
                                for s, v in stage_seconds.items()}}
    if model.name == "two-finger":
        index = [model.state_index(f"index.{j}") for j in ("mcp", "pip", "dip")]
        middle = [model.state_index(f"middle.{j}") for j in ("mcp", "pip", "dip")]
        out["index_joint_rms_deg"] = float(np.degrees(np.sqrt(np.mean(
            (est[:, index] - truth[:, index]) ** 2))))
        out["middle_max_deviation_rad"] = float(np.abs(est[:, middle] - truth[:, middle]).max())
    return out


def visibility_agreement(name: str, n_states: int, seed: int = 0) -> dict:
    """Agreement of predicted orders with the renderer over random states near the
    scenario's motion (joints moved by up to 0.3 rad), and ms per order prediction."""
    scenario = build_scenario(name)
    model, cam = scenario.model, scenario.rig[0]
    parts = template_parts(model)
    rng = np.random.default_rng(seed)
    joints = np.array([k == "angle" for k in model.state_kinds])
    agree = contested = 0
    seconds = 0.0
    for _ in range(n_states):
        q = scenario.states[rng.integers(len(scenario.states))].copy()
        q[joints] += rng.uniform(-0.3, 0.3, joints.sum())
        q = np.clip(q, model.lower, model.upper)
        kin = forward_kinematics(model, q)
        labels = render_views(model, q, [cam], RenderOptions(), rng=0)[0].labels
        tic = time.perf_counter()
        windows = image_windows(parts, [facing_plane(p, kin, cam) for p in parts], kin, cam)
        order = predict_visibility(parts, windows, cam)
        seconds += time.perf_counter() - tic
        result = order_agreement(parts, kin, cam, labels, order)
        agree += result.agree
        contested += result.contested
    return {"scenario": name, "states": n_states, "contested_pixels": contested,
            "agreement": agree / contested if contested else 1.0,
            "ms_per_order": 1e3 * seconds / n_states}


def desk_pair(n_frames: int = DESK_FRAMES) -> list[dict]:
    """The desk rows (module docstring): per appearance and hand one render
    (:func:`~digiteyes.benchmarks.accuracy.scenario_for`, ``bench accuracy``'s motion and
    noise), tracked by both template trackers at their defaults and with
    :data:`CURL_SEARCH`; the figures of
    :func:`~digiteyes.benchmarks.accuracy.row_figures` per row."""
    rows = []
    for appearance in APPEARANCES:
        for hand in HANDS:
            sequence = render_sequence(scenario_for("desk", hand, n_frames),
                                       appearance=appearance)
            for tracker in ("templates", "templates+features"):
                for label, settings in (("default", {}), ("+curl search", CURL_SEARCH)):
                    options = replace(LayeredTemplateOptions(), **settings)
                    outcome = track_sequence(sequence, options, tracker=tracker)
                    figures = row_figures(sequence, outcome)
                    rows.append({"tracker": tracker, "setting": label,
                                 "appearance": appearance, "hand": hand,
                                 "frames_per_second": 1e3 / max(figures["ms_per_frame"],
                                                                1e-6)}
                                | {k: figures[k] for k in (
                                    "fingertip_err_mm_mean", "worst_frame_tip_err_mm",
                                    "frames_tip_err_above_30mm", "truly_lost_frames",
                                    "flag")})
    return rows


def desk_lines(rows: list[dict]) -> list[str]:
    """The desk rows as table lines."""
    lines = ["desk pair (two cameras, 45 degrees above a palm-down hand; target: no frame "
             "above 30 mm)",
             f"{'tracker':<19} {'setting':<13} appearance hand    tip mm  worst mm  >30 mm"
             "  truly lost  flag P/R      fps"]
    for r in rows:
        flag = r["flag"]
        pr = "/".join("-" if flag[k] is None else f"{100 * flag[k]:.0f}"
                      for k in ("precision", "recall"))
        lines.append(f"{r['tracker']:<19} {r['setting']:<13} {r['appearance']:<10} "
                     f"{r['hand']:<6} {r['fingertip_err_mm_mean']:>7.2f} "
                     f"{r['worst_frame_tip_err_mm']:>9.2f} {r['frames_tip_err_above_30mm']:>7d}"
                     f" {r['truly_lost_frames']:>11d}  {pr:<9} {r['frames_per_second']:>6.1f}")
    return lines


def seed_mean(runs: list[dict]) -> dict:
    """One row from the runs of the same setting on several seeds: the figures of
    ``_AVERAGED`` and the stage times averaged, each seed's figures under ``per_seed``,
    the per-frame errors of each seed under ``tip_error_per_frame_mm`` (one list per
    seed)."""
    first = runs[0]
    row = {k: v for k, v in first.items() if k not in (*_AVERAGED, "seed")}
    row["seeds"] = [r["seed"] for r in runs]
    row["per_seed"] = {k: [r[k] for r in runs] for k in _AVERAGED if k in first}
    for key, values in row["per_seed"].items():
        row[key] = float(np.mean([np.nan if v is None else v for v in values]))
    row["tip_error_per_frame_mm"] = [r["tip_error_per_frame_mm"] for r in runs]
    row["ms_per_iteration"] = {s: float(np.mean([r["ms_per_iteration"][s] for r in runs]))
                               for s in first["ms_per_iteration"]}
    return row


_LABEL = len("templates+features +curl search")
"""Width of the table's tracker column (the longest :func:`run_label`)."""


def run_label(row: dict) -> str:
    """A row's tracker and the options it runs with beyond the defaults."""
    rig = TemplateOptions().for_rig(row["cameras"])  # the defaults as its rig uses them
    return (row["tracker"] + (" +search" if row["finger_search"] else "")
            + (" +curl search" if row.get("curl_search") else "")
            + (" +background" if row.get("background", "none") != "none" else "")
            + _off_default(row, "refresh_gated", rig.refresh_turn_deg is not None, " +gated",
                           " ungated")
            + _off_default(row, "pixel_depth_at_joints", rig.pixel_depth_at_joints,
                           " +pixel depth", " joint rule")
            + _off_default(row, "hiding_costs", rig.hidden_residual > 0, " +hiding cost",
                           " free hiding"))


def _off_default(row: dict, key: str, default: bool, on: str, off: str) -> str:
    """``on`` or ``off`` where a row's setting ``key`` is not ``default``, its rig's
    default (a row without the key has the default), else nothing."""
    value = row.get(key, default)
    return "" if value == default else on if value else off


def run(json_path: str | None = None, quick: bool = False) -> dict:
    """Run the benchmark, print a table, optionally write JSON (see module docstring)."""
    options = LayeredTemplateOptions()
    searching = replace(options, finger_search=True)
    curling = replace(options, **CURL_SEARCH)
    background = replace(options, background="filtered")

    def with_templates(**settings) -> LayeredTemplateOptions:
        return replace(options, templates=replace(options.templates, **settings))

    ungated = with_templates(refresh_turn_deg=None)
    gated = with_templates(refresh_turn_cameras=2)
    joint_rule = with_templates(pixel_depth_at_joints=False)
    by_pixel = with_templates(pixel_depth_at_joints=True)
    free_hiding = with_templates(hidden_residual=0.0)
    hiding_costs = with_templates(hidden_residual=HIDDEN_RESIDUAL_RIG)
    short = 40 if quick else None
    runs = [("two-finger-occlusion", 1, 30 if quick else None, "templates", options),
            ("two-finger-occlusion", 1, 30 if quick else None, "templates+features", options),
            ("two-finger-occlusion", 1, 30 if quick else None, "templates", background),
            ("two-finger-occlusion", 1, 30 if quick else None, "templates", ungated),
            ("two-finger-occlusion", 1, 30 if quick else None, "templates+features", ungated),
            ("natural", 2, short, "templates", options),
            ("natural", 2, short, "templates+features", options),
            ("natural", 1, short, "templates", options),
            ("natural", 2, short, "templates", searching),
            ("natural", 2, short, "templates+features", searching),
            ("natural", 1, short, "templates+features", searching),
            ("natural", 2, short, "templates", gated),
            ("natural", 2, short, "templates+features", gated),
            ("natural", 2, short, "templates", joint_rule),
            ("natural", 2, short, "templates+features", joint_rule),
            ("two-finger-occlusion", 1, 30 if quick else None, "templates", by_pixel),
            ("natural", 2, short, "templates", free_hiding),
            ("natural", 2, short, "templates+features", free_hiding),
            ("two-finger-occlusion", 1, 30 if quick else None, "templates", hiding_costs),
            ("natural", 2, short, "templates", curling),
            ("natural", 2, short, "templates+features", curling),
            ("natural", 1, short, "templates", curling),
            ("natural", 1, short, "templates+features", curling)]
    seeds = SEEDS[:1] if quick else SEEDS
    with kernel_threads(1, 1):
        tracking = [seed_mean([track_scenario(n, c, f, o, t, a, seed) for seed in seeds])
                    for n, c, f, t, o in runs for a in APPEARANCES]
        visibility = [visibility_agreement(n, 5 if quick else 30)
                      for n in ("two-finger-occlusion", "natural")]
        desk = desk_pair(20 if quick else DESK_FRAMES)
    topts = options.templates
    settings = {"iterations_per_frame": options.iterations_per_frame,
                "template_weight": options.template_weight,
                "conditioning": list(options.conditioning), "log": asdict(topts.log),
                "window": topts.window, "refresh_rate": topts.refresh_rate,
                "refresh_turn_deg": topts.refresh_turn_deg,
                "refresh_turn_cameras": topts.refresh_turn_cameras,
                "filter_pad_px": topts.filter_pad_px, "finger_search": options.finger_search,
                "pixel_depth_at_joints": topts.pixel_depth_at_joints,
                "hidden_residual": topts.hidden_residual,
                "hidden_residual_rig": HIDDEN_RESIDUAL_RIG,
                "seeds": list(seeds), "noise_sigma": NOISE_SIGMA,
                "curl_search": CURL_SEARCH}
    result = {"tracking": tracking, "visibility": visibility, "desk_pair": desk,
              "settings": settings,
              "machine": machine_info(), "quick": quick}
    lines = [*machine_lines(result["machine"]), "",
             f"mean over {len(seeds)} noise seed(s); tip mm: mean (lowest-highest seed)", "",
             f"scenario              {'tracker':<{_LABEL}} appearance cams frames"
             "  tip mm (range)       max mm  flagged  truly lost   fps  idx RMS deg"
             "  mid dev rad"]
    for t in tracking:
        low, high = min(t["per_seed"]["mean_tip_error_mm"]), max(
            t["per_seed"]["mean_tip_error_mm"])
        label = run_label(t)
        lines.append(f"{t['scenario']:<21} {label:<{_LABEL}} {t['appearance']:<10} "
                     f"{t['cameras']:>4} "
                     f"{t['frames']:>6} "
                     f"{t['mean_tip_error_mm']:>7.2f} ({low:>6.2f}-{high:<6.2f}) "
                     f"{t['max_frame_tip_error_mm']:>7.2f} "
                     f"{t['lost_frames']:>8.1f} {t['truly_lost_frames']:>11.1f} "
                     f"{t['frames_per_second'] or 0:>5.1f}  "
                     f"{t.get('index_joint_rms_deg', float('nan')):>11.2f}  "
                     f"{t.get('middle_max_deviation_rad', float('nan')):>11.3f}")
    lines += ["", "ms per iteration: " + ", ".join(STAGES)]
    for t in tracking:
        label = run_label(t)
        lines.append(f"{t['scenario']:<21} {label:<{_LABEL}} {t['appearance']:<6} "
                     f"{t['cameras']} cam: " + "  ".join(
            f"{t['ms_per_iteration'][s]:.2f}" for s in STAGES))
    lines += ["", *desk_lines(desk)]
    lines += ["", "visibility order vs depth buffer"]
    for v in visibility:
        lines.append(f"{v['scenario']:<22} agreement {v['agreement']:.3f} over "
                     f"{v['contested_pixels']} contested px, {v['ms_per_order']:.2f} ms/order")
    return emit(result, "\n".join(lines), json_path)
