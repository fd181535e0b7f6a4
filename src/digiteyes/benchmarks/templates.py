"""Layered template benchmark: accuracy and speed of the template trackers on the
synthetic scenarios, and agreement of the predicted visibility orders with the renderer.

Each scenario is tracked with the templates alone and (except ``natural`` with one
camera) with templates plus edge features, in both appearances of the renderer: the
tracking model's own drawing (``model``) and the independent flesh hand (``flesh``,
docs/appearance.md), side by side.

* ``two-finger-occlusion`` (thesis Sec. 4.4.2, one camera, 80 frames): largest deviation
  of the middle finger's joints from the truth (rad; target 0.03), index joint-angle RMS
  (deg; target 3), mean fingertip error (mm; target 3), lost frames (target 0);
* ``natural`` (Huang et al., 200 frames): mean fingertip error with two cameras (target
  8 mm) and one (15 mm), lost frames;
* speed: frames per second of ``step`` (rendering excluded, the first frame with the
  template acquisition and compilation excluded) and milliseconds per iteration split
  into visibility, template rendering (placing template pixels), residual (the compiled
  pass), Jacobian (chaining into ``H``, ``g``), edge features (combined tracker) and
  solve;
* visibility: share of contested pixels where the predicted front part is the one the
  renderer's depth buffer shows, over random states, and the time to predict an order.

OpenCV and numba are held to one thread. ``digiteyes bench templates [--json FILE]
[--quick]`` (``--quick``: fewer frames and states).
"""

from __future__ import annotations

import time
from dataclasses import asdict, fields

import numpy as np

from digiteyes.benchmarks._machine import emit, kernel_threads, machine_info, machine_lines
from digiteyes.camera import Rig
from digiteyes.kinematics import forward_kinematics
from digiteyes.occlusion.agreement import order_agreement
from digiteyes.occlusion.parts import facing_plane, template_parts
from digiteyes.occlusion.visibility import predict_visibility
from digiteyes.occlusion.windows import image_windows
from digiteyes.pipeline import step_frames
from digiteyes.synth import RenderOptions, render_views
from digiteyes.synth.options import APPEARANCES
from digiteyes.synth.scenarios import build_scenario
from digiteyes.trackers import LayeredTemplateOptions, create_tracker

STAGES = ("visibility", "template_rendering", "residual", "jacobian", "features",
          "linear_solve")


def track_scenario(name: str, n_cameras: int, n_frames: int | None,
                   options: LayeredTemplateOptions, tracker: str = "templates",
                   appearance: str = "model") -> dict:
    """Render a scenario in ``appearance`` (:data:`~digiteyes.synth.options.APPEARANCES`),
    track it from its first true state with the registered ``tracker`` (created by
    :func:`~digiteyes.trackers.create_tracker`, stepped by the run loop
    :func:`~digiteyes.pipeline.step_frames`) and score it against the truth (figures of
    the module docstring)."""
    scenario = build_scenario(name, n_frames=n_frames)
    model = scenario.model
    rig = Rig(scenario.rig.cameras[:n_cameras])
    render = RenderOptions(appearance=appearance)
    frames = [[v.image for v in render_views(model, q, rig, render, rng=i)]
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
    tips = [link.row for link in model.links if link.kind == "tip"]
    kt = forward_kinematics(model, truth).T_world_shape[:, tips][..., :3, 3]
    ke = forward_kinematics(model, est).T_world_shape[:, tips][..., :3, 3]
    tip_error = np.linalg.norm(kt - ke, axis=2)  # (frames, tips)
    per_frame = tip_error.mean(axis=1)
    out = {"scenario": name, "tracker": tracker, "appearance": appearance,
           "cameras": n_cameras,
           "frames": len(truth),
           "iterations_per_frame": options.iterations_per_frame,
           "mean_tip_error_mm": float(tip_error.mean()),
           "max_frame_tip_error_mm": float(per_frame.max()),
           "tip_error_per_frame_mm": [round(float(e), 2) for e in per_frame],
           "lost_frames": int(lost),
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


def run(json_path: str | None = None, quick: bool = False) -> dict:
    """Run the benchmark, print a table, optionally write JSON (see module docstring)."""
    options = LayeredTemplateOptions()
    runs = [("two-finger-occlusion", 1, 30 if quick else None, "templates"),
            ("two-finger-occlusion", 1, 30 if quick else None, "templates+features"),
            ("natural", 2, 40 if quick else None, "templates"),
            ("natural", 2, 40 if quick else None, "templates+features"),
            ("natural", 1, 40 if quick else None, "templates")]
    with kernel_threads(1, 1):
        tracking = [track_scenario(n, c, f, options, t, a) for n, c, f, t in runs
                    for a in APPEARANCES]
        visibility = [visibility_agreement(n, 5 if quick else 30)
                      for n in ("two-finger-occlusion", "natural")]
    topts = options.templates
    settings = {"iterations_per_frame": options.iterations_per_frame,
                "template_weight": options.template_weight, "log": asdict(topts.log),
                "window": topts.window, "refresh_rate": topts.refresh_rate,
                "filter_pad_px": topts.filter_pad_px, "finger_search": options.finger_search}
    result = {"tracking": tracking, "visibility": visibility, "settings": settings,
              "machine": machine_info(), "quick": quick}
    lines = [*machine_lines(result["machine"]), "",
             "scenario              tracker            appearance cams frames  tip mm  max mm"
             "  lost   fps  idx RMS deg  mid dev rad"]
    for t in tracking:
        lines.append(f"{t['scenario']:<21} {t['tracker']:<18} {t['appearance']:<10} "
                     f"{t['cameras']:>4} "
                     f"{t['frames']:>6} "
                     f"{t['mean_tip_error_mm']:>7.2f} {t['max_frame_tip_error_mm']:>7.2f} "
                     f"{t['lost_frames']:>5} {t['frames_per_second'] or 0:>5.1f}  "
                     f"{t.get('index_joint_rms_deg', float('nan')):>11.2f}  "
                     f"{t.get('middle_max_deviation_rad', float('nan')):>11.3f}")
    lines += ["", "ms per iteration: " + ", ".join(STAGES)]
    for t in tracking:
        lines.append(f"{t['scenario']:<21} {t['tracker']:<18} {t['appearance']:<6} "
                     f"{t['cameras']} cam: " + "  ".join(
            f"{t['ms_per_iteration'][s]:.2f}" for s in STAGES))
    lines += ["", "visibility order vs depth buffer"]
    for v in visibility:
        lines.append(f"{v['scenario']:<22} agreement {v['agreement']:.3f} over "
                     f"{v['contested_pixels']} contested px, {v['ms_per_order']:.2f} ms/order")
    return emit(result, "\n".join(lines), json_path)
