"""Divide-and-conquer benchmark (Huang, Wu & Lin; provisional figures).

Measured, one core (OpenCV and numba kernels held to one thread), 640x480, one camera of
the ``natural`` scenario:

* ``likelihoods_per_s``: full finger-set likelihoods (Huang Sec. 5.2, every finger patch,
  occlusion map) per second for a batch of 3000 hypotheses, for ``cardboard-hand`` and
  ``hand``, with the share of the time spent in batched forward kinematics;
* ``trackers``: per-frame time and accuracy (finger joint-angle RMS, palm orientation and
  position error, against the scenario's truth) of :class:`DivideConquerTracker` (300
  particles), :class:`CondensationTracker` (3000) and :class:`RandomSearchTracker` (5000)
  on the first frames of ``natural`` rendered with the cardboard hand;
* ``fig3``: Huang Fig. 3 with truth: the three trackers' finger joint-angle RMS per frame
  on ``natural`` and on the CyberGlove-driven ``glove-desk-1cam`` (skipped, with the
  reason, when the glove data are absent), one camera, plotted to ``--plot``; the images
  drawn from the tracking model (the cardboard hand) and, as ``fig3_flesh``, from the
  independent flesh hand driven by the same states (docs/appearance.md). Each run is made
  with the trackers' random draws of :data:`FIG3_SEEDS` (the order of the trackers can
  change with them); a record holds seed 0's figures and per-frame series, and under
  ``seeds`` every seed's mean and largest error and their mean over the seeds.

Run with ``digiteyes bench smc [--json FILE] [--quick]``.
"""

from __future__ import annotations

import statistics
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

from digiteyes.benchmarks._machine import emit, kernel_threads, machine_info, seconds_per_call
from digiteyes.errors import DigitEyesError
from digiteyes.evaluate.truth_loss import truth_loss
from digiteyes.kinematics import forward_kinematics, load_model
from digiteyes.smc.digit_search import DigitSearchOptions
from digiteyes.smc.likelihood import (
    FingerGeometry,
    edge_lookup,
    finger_log_likelihood,
    observe_edges,
)
from digiteyes.smc.palm import palm_pose_from_state
from digiteyes.smc.prior import default_configuration_space
from digiteyes.synth import RenderOptions, render_views
from digiteyes.synth.options import APPEARANCES
from digiteyes.synth.scenarios import build_scenario
from digiteyes.trackers.divide_conquer import (
    CondensationTracker,
    DivideConquerOptions,
    DivideConquerTracker,
    RandomSearchTracker,
)

BATCH = 3000
FIG3_SCENARIOS = ("natural", "glove-desk-1cam")
FIG3_TRACKERS = (DivideConquerTracker, CondensationTracker, RandomSearchTracker)
HUANG_ONLY = DivideConquerOptions(digit_search=DigitSearchOptions(passes=0),
                                  digit_resampling=False)
"""The proposed tracker without our digit search: Huang's method alone."""
FIG3_RUNS = {
    "DivideConquerTracker": (DivideConquerTracker, None),
    "DivideConquerTracker, Huang only": (DivideConquerTracker, HUANG_ONLY),
    "CondensationTracker": (CondensationTracker, None),
    "RandomSearchTracker": (RandomSearchTracker, None),
}
"""Fig. 3 runs: label -> (tracker class, options or None for its defaults). "Huang only"
is the proposed tracker without our digit search (:mod:`digiteyes.smc.digit_search`);
the baselines are Huang's and never search digit by digit."""
FIG3_SEEDS = (0, 1, 2)
"""Tracker seeds of the Fig. 3 runs (``--quick``: the first)."""
LONG_RUN_FRAMES = 200
LONG_RUN_SEEDS = tuple(range(16))
"""Tracker seeds of the long run: one tracker's figures vary widely from seed to seed
(the same images; docs/divide-and-conquer.md), and changes nil in exact arithmetic move
the mean of eight by 1-2 mm, so the mean is over sixteen."""
APPEARANCE_LABELS = {"model": "own drawing", "flesh": "flesh hand"}


def _scenario_states(model, scenario) -> np.ndarray:
    if model.n_q == scenario.model.n_q:
        return scenario.states
    return np.delete(scenario.states, scenario.model.state_index("thumb.mp_abd"), axis=1)


def _likelihood_rates(repeat: int, min_time: float) -> dict:
    scenario = build_scenario("natural", n_frames=40)
    cam = scenario.rig.cameras[0]
    out = {}
    for name in ("cardboard-hand", "hand"):
        model = load_model(name)
        states = _scenario_states(model, scenario)
        q = states[30]
        edges = observe_edges(render_views(model, q, [cam], rng=0)[0].image)
        geometry = FingerGeometry.of(model)
        idx = default_configuration_space(model).joint_indices(model)
        Q = np.repeat(q[None], BATCH, axis=0)
        Q[:, idx] += np.random.default_rng(0).normal(0, 0.2, (BATCH, len(idx)))
        lookup = [edge_lookup(edges)]
        full = min(seconds_per_call(
            lambda m=model, g=geometry, Q=Q, e=edges, k=lookup: finger_log_likelihood(
                m, g, Q, [cam], [e], lookups=k), repeat, min_time))
        fk = min(seconds_per_call(lambda m=model, Q=Q: forward_kinematics(m, Q).T_world_shape,
                                  repeat, min_time))
        out[name] = {"likelihoods_per_s": BATCH / full, "us_per_likelihood": 1e6 * full / BATCH,
                     "forward_kinematics_share": fk / full}
    return out


def _finger_rms_deg(joint_index: np.ndarray, q: np.ndarray, truth: np.ndarray) -> float:
    """RMS over the finger joints ``joint_index`` of ``q - truth``, degrees."""
    return float(np.degrees(np.sqrt(np.mean((q[joint_index] - truth[joint_index]) ** 2))))


def _frames(n_frames: int, scenario_name: str = "natural", appearance: str = "model"):
    """(model, camera, true states, images) of the first ``n_frames`` of a scenario drawn in
    ``appearance``, one camera, the cardboard hand as the tracking model."""
    scenario = build_scenario(scenario_name, n_frames=max(n_frames, 20))
    n_frames = min(n_frames, len(scenario.states))
    cam = scenario.rig.cameras[0]
    model = load_model("cardboard-hand")
    states = _scenario_states(model, scenario)[:n_frames]
    render = RenderOptions(appearance=appearance)
    images = [render_views(model, states[f], [cam], render, rng=f)[0].image
              for f in range(n_frames)]
    return model, cam, states, images


def _track(cls, n_frames: int, scenario_name: str = "natural",
           appearance: str = "model", options=None, frames=None) -> dict:
    """Track with ``cls`` (options: its defaults unless given) from the true first state
    and score it against the truth; ``frames``: a :func:`_frames` result to reuse."""
    model, cam, states, images = frames or _frames(n_frames, scenario_name, appearance)
    tracker = cls(model, [cam], options=options)
    tracker.reset(states[0])
    times, joint, palm_deg, palm_mm, estimates, flagged = [], [], [], [], [], []
    for f, image in enumerate(images):
        t = time.perf_counter()
        r = tracker.step([image])
        times.append(time.perf_counter() - t)
        estimates.append(r.state)
        flagged.append(r.lost)
        idx = tracker.joint_index
        joint.append(_finger_rms_deg(idx, r.state, states[f]))
        Ta, Tb = palm_pose_from_state(model, r.state), palm_pose_from_state(model, states[f])
        palm_deg.append(np.degrees(np.arccos(np.clip((np.trace(Ta[:3, :3].T @ Tb[:3, :3]) - 1)
                                                     / 2, -1, 1))))
        palm_mm.append(float(np.linalg.norm(Ta[:3, 3] - Tb[:3, 3])))
    truth = truth_loss(model, np.array(estimates), states)
    return {"particles": tracker.options.n_particles, "frames": len(images),
            "ms_per_frame_median": 1e3 * statistics.median(times[1:] or times),
            "frames_per_s": 1.0 / statistics.median(times[1:] or times),
            "finger_rms_deg_mean": float(np.mean(joint)),
            "finger_rms_deg_max": float(np.max(joint)),
            "palm_deg_mean": float(np.mean(palm_deg)), "palm_mm_mean": float(np.mean(palm_mm)),
            "fingertip_mm_mean": float(truth.mean_tip_error_mm.mean()),
            "truly_lost_frames": int(truth.lost.sum()),
            "flagged_frames": int(np.sum(flagged)),
            "finger_rms_deg_per_frame": [float(e) for e in joint]}


RECOVERY_OFFSET_DEG = 30.0
RECOVERY_FRAMES = 20
RECOVERY_CONVERGED_DEG = 5.0


def _recovery(n_frames: int = RECOVERY_FRAMES) -> dict:
    """Issue 15's recovery target, both appearances: :class:`DivideConquerTracker` at its
    defaults (palm tracked) started with every finger flexion joint (MCP, PIP, DIP of the
    four fingers) :data:`RECOVERY_OFFSET_DEG` off (clipped to the limits) on ``natural``;
    the finger joint RMS per frame and the first frame below
    :data:`RECOVERY_CONVERGED_DEG` (None: never)."""
    out = {}
    for appearance in APPEARANCES:
        model, cam, states, images = _frames(n_frames, "natural", appearance)
        start = states[0].copy()
        for finger in ("index", "middle", "ring", "little"):
            for joint in ("mcp", "pip", "dip"):
                start[model.state_index(f"{finger}.{joint}")] += np.radians(RECOVERY_OFFSET_DEG)
        start = np.clip(start, model.lower, model.upper)
        tracker = DivideConquerTracker(model, [cam])
        tracker.reset(start)
        idx = tracker.joint_index
        errors = [_finger_rms_deg(idx, tracker.step([image]).state, states[f])
                  for f, image in enumerate(images)]
        below = [f for f, e in enumerate(errors) if e < RECOVERY_CONVERGED_DEG]
        out[appearance] = {
            "start_error_deg": _finger_rms_deg(idx, start, states[0]),
            "first_frame_below": below[0] if below else None,
            "finger_rms_deg_per_frame": errors}
    return out


def _long_run(n_frames: int, seeds: tuple[int, ...]) -> dict:
    """Issue 15's long-run target: ``natural`` (``n_frames``, one camera) tracked by
    :class:`DivideConquerTracker` with and without the digit search (Huang alone), for
    each seed and appearance; per run the :func:`_track` record without the per-frame
    series, and the mean (``mean``) and the smallest and largest value over seeds
    (``range``) of each figure."""
    variants = {"proposed": DivideConquerOptions(), "huang_only": HUANG_ONLY}
    out = {}
    for appearance in APPEARANCES:
        frames = _frames(n_frames, "natural", appearance)
        out[appearance] = {}
        for name, options in variants.items():
            runs = []
            for seed in seeds:
                record = _track(DivideConquerTracker, n_frames,
                                options=replace(options, seed=seed), frames=frames)
                record.pop("finger_rms_deg_per_frame")
                runs.append(record | {"seed": seed})
            keys = ("finger_rms_deg_mean", "palm_deg_mean", "palm_mm_mean",
                    "fingertip_mm_mean", "truly_lost_frames", "flagged_frames")
            out[appearance][name] = {
                "runs": runs,
                "mean": {k: float(np.mean([r[k] for r in runs])) for k in keys},
                "range": {k: [float(min(r[k] for r in runs)), float(max(r[k] for r in runs))]
                          for k in keys}}
    return out


def _span(low_high: list[float], fmt: str) -> str:
    """``low-high`` of a figure's smallest and largest value over seeds."""
    return f"{low_high[0]:{fmt}}-{low_high[1]:{fmt}}"


def _fig3(n_frames: int, appearance: str = "model",
          seeds: tuple[int, ...] = FIG3_SEEDS) -> dict:
    """Per scenario of :data:`FIG3_SCENARIOS`: each tracker's :func:`_track` record of the
    first of ``seeds`` on images drawn in ``appearance``, with every seed's finger
    joint-angle RMS (mean and largest over the frames) and their means over the seeds
    under ``seeds``; or ``{"skipped": reason}`` when the scenario cannot be built (no
    glove data)."""
    out = {}
    for name in FIG3_SCENARIOS:
        try:
            build_scenario(name, n_frames=2)
        except DigitEyesError as exc:
            out[name] = {"skipped": str(exc)}
            continue
        frames = _frames(n_frames, name, appearance)
        out[name] = {}
        for label, (cls, options) in FIG3_RUNS.items():
            base = options or cls.options_type()
            runs = [_track(cls, n_frames, options=replace(base, seed=seed), frames=frames)
                    for seed in seeds]
            means = [r["finger_rms_deg_mean"] for r in runs]
            peaks = [r["finger_rms_deg_max"] for r in runs]
            out[name][label] = runs[0] | {"seeds": {
                "seeds": list(seeds), "finger_rms_deg_mean": means,
                "finger_rms_deg_max": peaks, "mean_over_seeds": float(np.mean(means)),
                "max_over_seeds": float(np.mean(peaks))}}
    return out


def plot_fig3(fig3: dict, path: str) -> str:
    """Huang Fig. 3 with truth: finger joint-angle RMS per frame, one panel per entry of
    ``fig3`` (panel title -> tracker records), two panels a row."""
    from digiteyes.viz.plots import new_figure, save_figure

    shown = {k: v for k, v in fig3.items() if "skipped" not in v}
    columns = min(max(len(shown), 1), 2)
    rows = -(-max(len(shown), 1) // columns)
    fig = new_figure(6.0 * columns, 3.8 * rows)
    axes = fig.subplots(rows, columns, squeeze=False).ravel()
    fig.subplots_adjust(left=0.08, right=0.98, bottom=0.14 / rows, top=1 - 0.1 / rows,
                        wspace=0.2, hspace=0.35)
    labels = {"DivideConquerTracker": "proposed (300)",
              "DivideConquerTracker, Huang only": "proposed without digit search (300)",
              "CondensationTracker":
              "CONDENSATION (3000)", "RandomSearchTracker": "random search (5000)"}
    for ax, (name, runs) in zip(axes, shown.items(), strict=False):
        for tracker, record in runs.items():
            ax.plot(record["finger_rms_deg_per_frame"], label=labels.get(tracker, tracker))
        ax.set_title(f"{name}, one camera")
        ax.set_xlabel("frame")
        ax.set_ylabel("finger joint-angle RMS error, deg")
        ax.legend()
    return str(save_figure(fig, path))


def run(json_path: str | None = None, quick: bool = False,
        plot_path: str | None = None) -> dict:
    """Measure likelihood throughput, tracker frames and the Fig. 3 comparison; print a
    table, optionally write JSON and the plot (``plot_path``; by default next to the JSON
    file, ``<json stem>-fig3.png``)."""
    if plot_path is None and json_path:
        plot_path = str(Path(json_path).with_suffix("")) + "-fig3.png"
    repeat, min_time = (2, 0.05) if quick else (5, 0.3)
    n_frames = 6 if quick else 40
    with kernel_threads(1, 1):
        rates = _likelihood_rates(repeat, min_time)
        trackers = {cls.__name__: _track(cls, n_frames) for cls in FIG3_TRACKERS}
        fig3 = {appearance: _fig3(10 if quick else 60, appearance,
                                  FIG3_SEEDS[:1] if quick else FIG3_SEEDS)
                for appearance in APPEARANCES}
        long_run = _long_run(12 if quick else LONG_RUN_FRAMES,
                             LONG_RUN_SEEDS[:1] if quick else LONG_RUN_SEEDS)
        recovery = _recovery(6 if quick else RECOVERY_FRAMES)
    lines = ["Divide and conquer (Huang et al.), one core, 640x480 (provisional)",
             f"{'model':<16}{'likelihoods/s':>15}{'us each':>10}{'FK share':>10}"]
    for name, r in rates.items():
        lines.append(f"{name:<16}{r['likelihoods_per_s']:>15,.0f}{r['us_per_likelihood']:>10.1f}"
                     f"{r['forward_kinematics_share']:>10.0%}")
    lines.append(f"\n{'tracker':<24}{'N':>6}{'ms/frame':>10}{'finger rms':>12}{'max':>7}"
                 f"{'palm deg':>10}{'palm mm':>9}")
    for name, r in trackers.items():
        lines.append(f"{name:<24}{r['particles']:>6}{r['ms_per_frame_median']:>10.0f}"
                     f"{r['finger_rms_deg_mean']:>12.1f}{r['finger_rms_deg_max']:>7.1f}"
                     f"{r['palm_deg_mean']:>10.1f}{r['palm_mm_mean']:>9.1f}")
    lines.append("\nFig. 3 (finger joint-angle RMS per frame, deg: mean / max, each the "
                 "mean over the tracker seeds)")
    panels = {f"{name}, {APPEARANCE_LABELS[appearance]}": runs
              for appearance, scenarios in fig3.items() for name, runs in scenarios.items()}
    for name, runs in panels.items():
        if "skipped" in runs:
            lines.append(f"{name}: skipped ({runs['skipped']})")
            continue
        lines.append(f"{name} ({next(iter(runs.values()))['frames']} frames): " + ", ".join(
            f"{t} {r['seeds']['mean_over_seeds']:.1f} / {r['seeds']['max_over_seeds']:.1f}"
            for t, r in runs.items()))
    lines.append(f"\nnatural, one camera, whole sequence, mean over seeds "
                 f"{', '.join(str(r['seed']) for r in long_run['model']['proposed']['runs'])}"
                 f"\n{'images':<13}{'tracker':<12}{'finger deg':>11}{'palm deg':>9}"
                 f"{'palm mm':>8}{'tip mm':>8}{'lost':>6}{'flagged':>8}"
                 f"{'tip mm, seeds':>16}{'lost, seeds':>13}")
    for appearance, variants in long_run.items():
        for name, record in variants.items():
            m = record["mean"]
            lines.append(f"{APPEARANCE_LABELS[appearance]:<13}{name:<12}"
                         f"{m['finger_rms_deg_mean']:>11.1f}{m['palm_deg_mean']:>9.1f}"
                         f"{m['palm_mm_mean']:>8.1f}{m['fingertip_mm_mean']:>8.1f}"
                         f"{m['truly_lost_frames']:>6.1f}{m['flagged_frames']:>8.1f}"
                         f"{_span(record['range']['fingertip_mm_mean'], '.1f'):>16}"
                         f"{_span(record['range']['truly_lost_frames'], '.0f'):>13}")
    lines.append(f"\nrecovery: every finger flexion joint {RECOVERY_OFFSET_DEG:.0f} deg off at "
                 f"the start (finger joint RMS, deg, frames 0-9; first frame below "
                 f"{RECOVERY_CONVERGED_DEG:.0f})")
    for appearance, r in recovery.items():
        lines.append(f"{APPEARANCE_LABELS[appearance]:<13} start {r['start_error_deg']:.1f}: "
                     + " ".join(f"{e:.1f}" for e in r["finger_rms_deg_per_frame"][:10])
                     + f"; first below: {r['first_frame_below']}")
    if plot_path:
        plot_fig3(panels, plot_path)
    result = {"likelihood": rates, "trackers": trackers, "fig3": fig3["model"],
              "fig3_flesh": fig3["flesh"], "long_run": long_run, "recovery": recovery,
              "batch": BATCH,
              "frames": n_frames, "quick": quick, "machine": machine_info()}
    return emit(result, "\n".join(lines), json_path)
