"""Feature-tracker benchmark: speed per Gauss-Newton iteration, end-to-end frame rate,
accuracy against ground truth on the synthetic scenarios, and ablations.

Five sections (DESIGN.md Sec. 7, issue 4 item 8), every figure measured on this machine:

a. **Cost per iteration** of the full hand (28 states, every link and tip measured,
   640 x 480 images), one camera of the whole-hand rig (*mono*) and both (*stereo*),
   split into the rows of thesis Table 4.1: forward kinematics, feature detection, state
   estimation = Jacobian (residual and Jacobian assembly) + linear solve, from
   :attr:`TrackResult.timings` summed over the frames and divided by the iterations. A
   frame measures the features ``iterations + 1`` times (once more at the final state
   for the reported residual), and that extra pass is charged to the iterations, as is
   the prediction and the bookkeeping between stages ("other"); the shading prediction,
   once per frame, is reported on its own (``shading_per_frame``, ms per frame, and
   ``total_with_shading``, the total with it charged to the iterations). Thesis figures (68040,
   stopwatch): 18.0, 46.2, 72.0 (35 + 37), plus 10.0 ms of overlay display that is not
   measured here; total 146 ms. Keys ``ms_per_iteration_mono``,
   ``ms_per_iteration_stereo``, ``per_iteration_mono``, ``per_iteration_stereo`` (ms per
   stage), ``speedup_vs_thesis_mono`` / ``_stereo`` (146 / ours).
b. **End-to-end frames per second** of ``digiteyes track`` on a video: the whole-hand
   sequence seen by camera 0 is written as video datasets in a temporary folder
   (:data:`E2E_VIDEOS`: H.264 at x264's default quality, CRF 23, about 2 KB per frame,
   the order of a phone recording, keys without suffix; near-lossless H.264 CRF 12,
   ``_crf12``; lossless FFV1, ``_ffv1``; ``kb_per_frame...`` their sizes), then opened,
   decoded and tracked with :func:`digiteyes.pipeline.run_tracker` (state log, summary,
   3D views every 50 frames and the trajectory plots, as the command writes them),
   without the overlay video (``fps_end_to_end``) and with it
   (``fps_end_to_end_overlay``): frames per second of the per-frame loop (the streaming
   rate), with ``_with_outputs`` of the whole command including the plots and views
   written at the end, with ``_tracker_only`` of the tracker's ``step`` calls. The
   iterations per frame (``fps_end_to_end_iterations``) are the fewest of 1-5 whose run
   on the CRF 23 video meets the one-camera targets (mean fingertip error <= 8 mm,
   joint-angle RMS <= 5 degrees) against the ground truth: that run's own accuracy
   decides (``e2e_runs``: the runs tried, and one at the default of 5; ``targets_met``
   false and 5 iterations if none meets them). numba's kernels use
   every core here, as in ``digiteyes track``; everywhere else one.
c. **Accuracy** (:func:`digiteyes.evaluate.evaluate_run`) of whole-hand mono (camera 0
   only), whole-hand stereo, mouse (one camera; also the error of the 3D-mouse pole
   height, :mod:`digiteyes.apps.mouse3d`), natural (stereo) and fast (stereo; track life
   matters) x background {black cloth, clutter} x model {exact, perturbed: the images
   come from a hand whose link lengths differ by up to 5 % (``perturb_model``) while the
   tracker keeps the nominal model}, at the iterations of (b) and at the tracker's
   default of 5 iterations per frame.
d. **Ablations** on whole-hand stereo, black cloth, exact model, from the tracker's
   defaults (``FeatureTrackerOptions()``: 5 iterations, tangent steps, conditioning, no
   robust loss, every link and tip): conditioning off, 1/2/3/5/10 iterations per frame,
   the other prediction (constant velocity vs the previous estimate), the thesis's
   quaternion form, Tukey loss, the thesis's link set.

e. **One camera's limit**: whole-hand camera 0 (black cloth, exact model, 5 iterations)
   rendered with the default Lambert shading and with flat shading (ambient light only),
   each tracked with the defaults (width residuals and shading correction,
   :mod:`digiteyes.features.appearance`), without the shading correction, and without
   the width residuals either, with the bias of the measured link widths at the true
   states (key ``shading``; docs/benchmarks.md (e)).

The images are rendered in memory (grey, sensor noise 2 grey levels, seeds as
``digiteyes render --seed 0``); nothing is kept on disk. OpenCV and numba's kernels run
on one thread (numba on every core in section (b)); NumPy's BLAS is limited to one
thread with ``threadpoolctl`` when it is importable, otherwise the table says how it runs
(set ``OPENBLAS_NUM_THREADS=1`` before starting for one thread). Run it with
``digiteyes bench tracker [--json FILE] [--quick]``; docs/benchmarks.md explains the
tables.
"""

from __future__ import annotations

import contextlib
import tempfile
import time
from collections.abc import Callable, Iterator, Mapping, Sequence
from dataclasses import dataclass, field, fields, replace
from pathlib import Path
from typing import Any

import numba
import numpy as np
from tqdm import tqdm

from digiteyes.apps.mouse3d import pole_from_state
from digiteyes.benchmarks._machine import (
    blas_info,
    emit,
    kernel_threads,
    machine_info,
    machine_lines,
)
from digiteyes.camera import Rig
from digiteyes.evaluate import evaluate_run
from digiteyes.features import FeatureOptions, feature_residuals, measure_features
from digiteyes.io import GroundTruth, SequenceWriter, StateLog, open_sequence, read_state_log
from digiteyes.io.video import VIDEO_CODECS
from digiteyes.kinematics import KinematicModel, forward_kinematics
from digiteyes.pipeline import TrackingRun, run_tracker, step_frames
from digiteyes.synth import RenderOptions
from digiteyes.synth.scenarios import Scenario, build_scenario
from digiteyes.synth.sequence import perturbed_truth, render_frames
from digiteyes.synth.setups import truth_model as truth_model_of
from digiteyes.trackers import (
    DEFAULT_TRACKER,
    FeatureTracker,
    FeatureTrackerOptions,
    create_tracker,
    thesis_whole_hand_links,
)

SEED = 0
"""Seed of the scenarios' motion, the sensor noise, the clutter and the perturbation."""
NOISE_SIGMA = 2.0
"""Sensor noise of the rendered images, grey levels."""
PERTURB_LINK_LENGTH = 0.05
"""Link-length perturbation of the "perturbed" true hand (fraction)."""

STAGES = tuple(s for s in FeatureTracker.stages if s in (
    "forward_kinematics", "feature_detection", "jacobian", "linear_solve"))
"""The stages of the feature tracker that are rows of thesis Table 4.1."""
THESIS_TABLE_4_1_MS = {
    "forward_kinematics": 18.0, "feature_detection": 46.2, "state_estimation": 72.0,
    "jacobian": 35.0, "linear_solve": 37.0, "overlay_display": 10.0, "total": 146.0,
}
"""Thesis Table 4.1: ms per iteration, full hand, 68040 CPU (overlay display included in
the total; the other rows add up to 136.2)."""

ACCURACY_TARGETS = {"fingertip_err_mm_mean": 3.0, "joint_angle_err_deg_rms": 5.0}
"""Issue 4's targets for whole-hand stereo (black cloth, exact model)."""
MONO_TARGETS = {"fingertip_err_mm_mean": 8.0, "joint_angle_err_deg_rms": 5.0}
"""Issue 4's targets for one camera: the end-to-end run (one camera's video) must meet
them at the iterations per frame its speed is reported for."""
DEFAULT_ITERATIONS = FeatureTrackerOptions().iterations_per_frame
E2E_ITERATION_CHOICES = (1, 2, 3, 4, 5)
E2E_CRF = 23
"""H.264 quality of the headline end-to-end video: x264's default constant rate factor.
It stores a rendered 640 x 480 frame in about 2 KB, the order of a phone recording (the
real hand video of the project's test data: 0.96 KB per 1280 x 720 frame); the
near-lossless CRF 12 keeps the sensor noise at some 80 KB per frame, and decoding that
costs about as much as tracking (docs/benchmarks.md (b))."""
E2E_VIDEOS = (("", "h264", E2E_CRF), ("_crf12", "h264", 12), ("_ffv1", "ffv1", 0))
"""Section (b)'s videos: (key suffix, codec, H.264 crf)."""

BACKGROUNDS = ("black", "clutter")
MODELS = ("exact", "perturbed")
ACCURACY_CASES = {
    # case: (scenario, cameras (None: all), pole error)
    "whole-hand mono": ("whole-hand", (0,), False),
    "whole-hand stereo": ("whole-hand", None, False),
    "mouse": ("mouse", None, True),
    "natural": ("natural", None, False),
    "fast": ("fast", None, False),
}

OTHER_PREDICTION = "constant-velocity" if FeatureTrackerOptions().prediction == "none" \
    else "none"
"""The prediction the tracker does not use by default (the prediction ablation)."""

ABLATIONS: dict[str, dict[str, Any]] = {
    f"defaults ({DEFAULT_ITERATIONS} it)": {},
    "no conditioning": {"use_conditioning": False},
    "1 iteration": {"iterations_per_frame": 1},
    "2 iterations": {"iterations_per_frame": 2},
    "3 iterations": {"iterations_per_frame": 3},
    "10 iterations": {"iterations_per_frame": 10},
    f"prediction {OTHER_PREDICTION}": {"prediction": OTHER_PREDICTION},
    "quaternion form": {"form": "quaternion"},
    "tukey loss (5 px)": {"robust_loss": "tukey"},
    "thesis link set": {"links": "thesis"},
}
"""Ablation variants: changes to the tracker's default options (``"links": "thesis"``
stands for :func:`thesis_whole_hand_links`: no middle and ring proximal phalanges)."""
QUICK_ABLATIONS = (f"defaults ({DEFAULT_ITERATIONS} it)", "no conditioning", "1 iteration",
                   "2 iterations", "3 iterations")


@dataclass(frozen=True)
class Settings:
    """How much a run does: frames per scenario (None: the scenario's own length), frames
    of the speed and end-to-end runs, the ablations, passes of the speed runs."""

    frames: int | None
    speed_frames: int
    e2e_frames: int | None
    ablations: tuple[str, ...]
    speed_passes: int


FULL = Settings(frames=None, speed_frames=100, e2e_frames=None, ablations=tuple(ABLATIONS),
                speed_passes=2)
QUICK = Settings(frames=30, speed_frames=15, e2e_frames=30, ablations=QUICK_ABLATIONS,
                 speed_passes=1)


# --------------------------------------------------------------------------- sequences
@dataclass(frozen=True)
class RenderedSequence:
    """A scenario rendered in memory: grey images per frame and camera, and the truth."""

    scenario: Scenario
    rig: Rig
    images: list[list[np.ndarray]]
    truth: GroundTruth
    truth_model: KinematicModel

    @property
    def n_frames(self) -> int:
        return len(self.images)

    def first(self, n: int) -> RenderedSequence:
        """The sequence's first ``n`` frames (all of them when it has no more)."""
        if n >= self.n_frames:
            return self
        t = self.truth
        truth = GroundTruth(None if t.states is None else t.states[:n], t.keypoint_names,
                            t.keypoints_3d[:n], t.keypoints_2d[:n], t.visible[:n])
        return replace(self, images=self.images[:n], truth=truth)

    def cameras(self, indices: Sequence[int] | None) -> RenderedSequence:
        """The same sequence seen by a subset of the cameras (None: all of them)."""
        if indices is None:
            return self
        idx = list(indices)
        truth = GroundTruth(self.truth.states, self.truth.keypoint_names,
                            self.truth.keypoints_3d, self.truth.keypoints_2d[:, idx],
                            self.truth.visible[:, idx])
        return replace(self, rig=Rig(tuple(self.rig.cameras[i] for i in idx)),
                       images=[[frame[i] for i in idx] for frame in self.images], truth=truth)


def render_sequence(scenario: Scenario, background: str = "black", perturbed: bool = False,
                    seed: int = SEED, progress: bool = False, flat: bool = False,
                    cameras: Sequence[int] | None = None,
                    appearance: str = "model", color: bool = False,
                    render: Mapping[str, Any] | None = None) -> RenderedSequence:
    """Render every frame of ``scenario`` through its rig (grey, noise
    :data:`NOISE_SIGMA`), from a hand perturbed by :data:`PERTURB_LINK_LENGTH` if asked
    and scaled by the scenario's ``hand_scale`` if it has one; seeds as ``digiteyes render
    --seed``. ``flat`` lights the skin evenly (ambient light only: no shading towards the
    silhouette); ``cameras`` renders only those cameras of the rig (None: all);
    ``appearance`` ``"model"`` or ``"flesh"`` (docs/appearance.md); ``color`` RGB images
    (what a learned detector needs) instead of grey; ``render``: further
    :class:`~digiteyes.synth.RenderOptions` fields that replace these settings (a noisier
    sensor, a darker skin, another light)."""
    truth_model, _ = perturbed_truth(truth_model_of(scenario),
                                     PERTURB_LINK_LENGTH if perturbed else 0.0, seed)
    options = RenderOptions(background=background, noise_sigma=NOISE_SIGMA,
                            background_seed=seed, appearance=appearance, color=color)
    if flat:
        options = replace(options, ambient=1.0)
    if render:
        options = replace(options, **render)
    rig = scenario.rig if cameras is None else Rig(tuple(scenario.rig.cameras[i]
                                                          for i in cameras))
    label = (f"render {scenario.name} {background} {'perturbed' if perturbed else 'exact'}"
             f"{' flat' if flat else ''} {appearance}{' colour' if color else ''}")
    frames = list(render_frames(scenario, options, seed=seed, truth_model=truth_model,
                                rig=rig, progress=progress, label=label))
    truth = GroundTruth(np.array(scenario.states, dtype=float), frames[0][1].keypoint_names,
                        np.array([f.keypoints_3d for _, f in frames]),
                        np.array([f.keypoints_2d for _, f in frames]),
                        np.array([f.visible for _, f in frames]))
    return RenderedSequence(scenario, rig, [images for images, _ in frames], truth,
                            truth_model)


# --------------------------------------------------------------------------- tracking
@dataclass
class TrackOutcome:
    """A tracker run over a rendered sequence: the log, the time spent per stage and the
    per-finger loss flags of every frame (``TrackResult.finger_lost``)."""

    log: StateLog
    stage_seconds: dict[str, float]
    tracker_seconds: float
    iterations: int
    features_per_frame: float
    finger_lost: list[dict[str, bool]] = field(default_factory=list)


def track_sequence(sequence: RenderedSequence, options: Any, label: str = "track",
                   progress: bool = False, tracker: str = DEFAULT_TRACKER) -> TrackOutcome:
    """Track ``sequence`` from its true first state with the registered ``tracker``
    (:func:`~digiteyes.trackers.create_tracker`; ``options`` an instance of its options
    type), through the run loop of ``digiteyes track``
    (:func:`~digiteyes.pipeline.step_frames`)."""
    model = sequence.scenario.model
    settings = {f.name: getattr(options, f.name) for f in fields(options)}
    runner = create_tracker(tracker, model, sequence.rig, **settings)
    n = sequence.n_frames
    states = np.empty((n, model.n_q))
    lost = np.zeros(n, dtype=bool)
    rms = np.full(n, np.nan)
    iterations = np.zeros(n, dtype=int)
    seconds = np.zeros(n)
    hand_scale = np.ones(n)
    stage = dict.fromkeys(runner.stages, 0.0)
    features = 0
    finger_lost: list[dict[str, bool]] = []
    frames = tqdm(sequence.images, desc=label, unit="frame", leave=False,
                  disable=not progress)
    for t, _, result, step_seconds in step_frames(runner, frames,
                                                  sequence.scenario.initial_state):
        seconds[t] = step_seconds
        states[t], lost[t], rms[t] = result.state, result.lost, result.residual_rms_px
        iterations[t], hand_scale[t] = result.iterations, result.hand_scale
        finger_lost.append(dict(result.finger_lost))
        features += getattr(result.details, "n_features", 0)
        for key in stage:
            stage[key] += result.timings.get(key, 0.0)
    log = StateLog(np.arange(n), states, lost, rms, iterations, seconds, hand_scale)
    return TrackOutcome(log, stage, float(seconds.sum()), int(iterations.sum()),
                        features / max(n, 1), finger_lost)


def _number(value: Any) -> float | None:
    """A finite float, or None (strict JSON)."""
    if value is None:
        return None
    value = float(value)
    return value if np.isfinite(value) else None


def accuracy_summary(sequence: RenderedSequence, outcome: TrackOutcome,
                     pole: bool = False) -> dict[str, Any]:
    """The per-run figures of section (c) from :func:`evaluate_run` (mm, degrees, px,
    frames), plus the 3D-mouse pole errors when ``pole``."""
    model = sequence.scenario.model
    metrics = evaluate_run(outcome.log, sequence.truth, model, sequence.rig)
    tip, palm = metrics["fingertip_error_mm"], metrics["palm"]
    angles, reprojection = metrics["joint_angle_error_deg"], metrics["reprojection_error_px"]
    n = len(outcome.log)
    out: dict[str, Any] = {
        "fingertip_err_mm_mean": _number(tip and tip["mean"]),
        "fingertip_err_mm_max": _number(tip and tip["max"]),
        "joint_angle_err_deg_rms": _number(angles and angles["rms"]),
        "palm_pos_err_mm_mean": _number(palm and palm["position_error_mm"]["mean"]),
        "palm_rot_err_deg_mean": _number(palm and palm["orientation_error_deg"]["mean"]),
        "reprojection_err_px_mean": _number(reprojection and reprojection["mean"]),
        "track_life_frames": int(metrics["track_life"]["frames"]),
        "frames": n,
        "lost_frames": int(metrics["run"]["lost_frames"]),
        "iterations_per_frame": outcome.iterations / max(n, 1),
        "ms_per_frame": 1e3 * outcome.tracker_seconds / max(n, 1),
    }
    if pole:
        estimate = pole_from_state(model, outcome.log.states)
        truth = pole_from_state(sequence.truth_model, sequence.truth.states[:n])
        out["pole_height_err_mm_mean"] = float(np.mean(np.abs(estimate[:, 2] - truth[:, 2])))
        out["pole_base_err_mm_mean"] = float(np.mean(
            np.linalg.norm(estimate[:, :2] - truth[:, :2], axis=1)))
    return out


def meets_targets(summary: dict[str, Any], targets: dict[str, float]) -> bool:
    """Whether a run meets ``targets`` (figure -> upper limit; a missing figure fails)."""
    return all(summary.get(key) is not None and summary[key] <= limit
               for key, limit in targets.items())


# --------------------------------------------------------------------------- sections
def per_iteration_ms(outcome: TrackOutcome) -> dict[str, float]:
    """Milliseconds per Gauss-Newton iteration by Table 4.1 row; ``other`` is the rest of
    the ``step`` time (prediction, grey conversion outside the timers, bookkeeping)
    except the shading prediction, which is once per frame and outside the thesis's loop:
    ``shading_per_frame`` (ms per frame) and ``total_with_shading`` (ms per iteration with
    it charged to the iterations too)."""
    k = 1e3 / max(outcome.iterations, 1)
    shading = outcome.stage_seconds["shading"]
    out = {stage: k * outcome.stage_seconds[stage] for stage in STAGES}
    out["state_estimation"] = out["jacobian"] + out["linear_solve"]
    out["total"] = k * (outcome.tracker_seconds - shading)
    out["other"] = out["total"] - sum(out[stage] for stage in STAGES)
    out["total_with_shading"] = k * outcome.tracker_seconds
    out["shading_per_frame"] = 1e3 * shading / max(len(outcome.log), 1)
    return out


def speed_section(sequence: RenderedSequence, settings: Settings, progress: bool
                  ) -> dict[str, Any]:
    """Section (a): ms per iteration, mono and stereo, best of the passes."""
    frames = min(settings.speed_frames, sequence.n_frames)
    clip = replace(sequence, images=sequence.images[:frames])
    out: dict[str, Any] = {"speed_frames": frames, "speed_passes": settings.speed_passes,
                           "speed_iterations_per_frame": DEFAULT_ITERATIONS}
    for label, cameras in (("mono", (0,)), ("stereo", None)):
        seq = clip.cameras(cameras)
        track_sequence(replace(seq, images=seq.images[:2]), FeatureTrackerOptions())  # warm
        passes = [track_sequence(seq, FeatureTrackerOptions(), f"speed {label}", progress)
                  for _ in range(settings.speed_passes)]
        best = min(passes, key=lambda o: o.tracker_seconds)
        stages = per_iteration_ms(best)
        stages["features_per_iteration"] = best.features_per_frame
        out[f"per_iteration_{label}"] = stages
        out[f"ms_per_iteration_{label}"] = stages["total"]
        out[f"speedup_vs_thesis_{label}"] = THESIS_TABLE_4_1_MS["total"] / stages["total"]
        out[f"speedup_vs_thesis_{label}_without_overlay"] = (
            THESIS_TABLE_4_1_MS["total"] - THESIS_TABLE_4_1_MS["overlay_display"]
        ) / stages["total"]
    out["thesis_table_4_1_ms"] = dict(THESIS_TABLE_4_1_MS)
    return out


def ablation_section(sequence: RenderedSequence, settings: Settings, progress: bool
                     ) -> dict[str, dict[str, Any]]:
    """Section (d): each variant on whole-hand stereo (black cloth, exact model)."""
    out = {}
    for name in settings.ablations:
        changes = dict(ABLATIONS[name])
        if changes.get("links") == "thesis":
            changes["links"] = thesis_whole_hand_links(sequence.scenario.model)
        options = FeatureTrackerOptions(**changes)
        outcome = track_sequence(sequence, options, f"ablation: {name}", progress)
        out[name] = accuracy_summary(sequence, outcome) | {"options": ABLATIONS[name]}
    return out


def width_bias(sequence: RenderedSequence, every: int = 5) -> dict[str, float]:
    """How far the measured link widths are from the true ones, measured at the true
    states of every ``every``-th frame in the first camera: ``width_bias_px_mean`` (mean
    of measured minus true width over every width row, px) and
    ``width_bias_px_link_rms`` (RMS over links of each link's mean bias: the part that
    bends the fingers rather than moving the whole hand)."""
    model, camera = sequence.scenario.model, sequence.rig.cameras[0]
    tracker = FeatureTracker(model, Rig((camera,)))
    by_link: dict[int, list[float]] = {}
    for t in range(0, sequence.n_frames, every):
        kin = forward_kinematics(model, sequence.truth.states[t])
        meas = measure_features(sequence.images[t][0], camera, model, kin, FeatureOptions(),
                                tracker.link_names, tracker.tip_names)
        r, _, layout = feature_residuals(meas, camera, kin, jacobian=False, width_weight=1.0)
        for row in layout.rows("width"):
            by_link.setdefault(int(layout.link_index[row]), []).append(-float(r[row]))
    means = np.array([np.mean(v) for v in by_link.values()])
    return {"width_bias_px_mean": float(np.mean(np.concatenate(list(by_link.values())))),
            "width_bias_px_link_rms": float(np.sqrt(np.mean(means**2)))}


SHADING_RUNS = {
    "corrected": FeatureTrackerOptions(),
    "with_width": FeatureTrackerOptions(shading_correction=False),
    "without_width": FeatureTrackerOptions(shading_correction=False, width_weight=0.0),
}
"""Section (e)'s runs: the defaults (width residuals, shading correction), without the
shading correction, and without the width residuals either."""


def shading_section(settings: Settings, progress: bool) -> dict[str, dict[str, Any]]:
    """Section (e): what limits one camera. Whole-hand seen by camera 0, black cloth,
    exact model, the default 5 iterations, with the renderer's Lambert shading and with
    flat shading: per shading the width bias (:func:`width_bias`) and the accuracy of
    each of :data:`SHADING_RUNS`."""
    whole = build_scenario("whole-hand", seed=SEED, n_frames=settings.frames)
    out: dict[str, dict[str, Any]] = {}
    for shading in ("lambert", "flat"):
        sequence = render_sequence(whole, progress=progress, flat=shading == "flat",
                                   cameras=(0,))
        out[shading] = width_bias(sequence)
        for label, options in SHADING_RUNS.items():
            outcome = track_sequence(sequence, options, f"shading: {shading} {label}",
                                     progress)
            out[shading][label] = accuracy_summary(sequence, outcome)
    return out


def iterations_run(ablations: dict[str, dict[str, Any]], k: int) -> dict[str, Any] | None:
    """The ablation run that differs from the defaults at most by ``k`` iterations per
    frame, or None."""
    for r in ablations.values():
        options = r["options"]
        if options == {"iterations_per_frame": k} or (not options and k == DEFAULT_ITERATIONS):
            return r
    return None


def choose_iterations(track_at: Callable[[int], dict[str, Any]]
                      ) -> tuple[int, bool, dict[int, dict[str, Any]]]:
    """Call ``track_at(k)`` (a run's figures) for k in :data:`E2E_ITERATION_CHOICES` until
    a run meets :data:`MONO_TARGETS`, then at the tracker's default too if it was not
    among them (its rate, for comparison). Returns the chosen k (the default if no run
    meets the targets), whether one did, and the figures of every run made."""
    runs: dict[int, dict[str, Any]] = {}
    chosen = None
    for k in E2E_ITERATION_CHOICES:
        runs[k] = track_at(k)
        if meets_targets(runs[k], MONO_TARGETS):
            chosen = k
            break
    if DEFAULT_ITERATIONS not in runs:
        runs[DEFAULT_ITERATIONS] = track_at(DEFAULT_ITERATIONS)
    return (DEFAULT_ITERATIONS, False, runs) if chosen is None else (chosen, True, runs)


def _video_dataset(sequence: RenderedSequence, frames: int, folder: Path, codec: str,
                   crf: int) -> tuple[Path, float]:
    """Write the first ``frames`` frames as a video dataset; returns the folder and the
    mean size of a frame in the video file(s), KB."""
    scenario = sequence.scenario
    with SequenceWriter(folder, scenario.model, sequence.rig, scenario.initial_state,
                        scenario.fps, video=codec, crf=crf) as writer:
        for images in sequence.images[:frames]:
            writer.write_frame(images)
    size = sum(p.stat().st_size for p in folder.glob(f"*{VIDEO_CODECS[codec][0]}"))
    return folder, size / 1024 / frames


def _track_video(folder: Path, iterations: int, overlay: bool, out_dir: Path
                 ) -> tuple[TrackingRun, float, StateLog]:
    """Decode and track a video dataset as ``digiteyes track`` does; returns the run, the
    frames per second of the whole command (with the final plots) and the state log."""
    start = time.perf_counter()
    with open_sequence(folder) as seq:
        tracker = create_tracker(DEFAULT_TRACKER, seq.model, seq.rig,
                                 iterations_per_frame=iterations)
        run = run_tracker(tracker, seq.model, seq.rig, iter(seq), seq.initial_state, out_dir,
                          fps=seq.fps, total=seq.n_frames, overlay=overlay, progress=False,
                          tracker_name=DEFAULT_TRACKER)
        log = read_state_log(run.files["states"], seq.model)
    return run, run.n_frames / (time.perf_counter() - start), log


def _rates(prefix: str, run: TrackingRun, with_outputs: float) -> dict[str, float]:
    return {prefix: run.loop_fps, f"{prefix}_with_outputs": with_outputs,
            f"{prefix}_tracker_only": run.tracker_fps}


def end_to_end_section(sequence: RenderedSequence, settings: Settings) -> dict[str, Any]:
    """Section (b): camera 0 written as video datasets (:data:`E2E_VIDEOS`), decoded and
    tracked as ``digiteyes track`` does, with no progress bar (it would be timed too).

    On the headline video (x264 at :data:`E2E_CRF`) the iterations per frame are the
    fewest whose run meets :data:`MONO_TARGETS` on that very run (:func:`choose_iterations`,
    keys ``e2e_runs``); the overlay video and the other videos are timed at that count."""
    mono = sequence.cameras((0,))
    frames = mono.n_frames if settings.e2e_frames is None else \
        min(settings.e2e_frames, mono.n_frames)
    truth = replace(mono, images=mono.images[:frames])
    out: dict[str, Any] = {"e2e_frames": frames, "e2e_crf": E2E_CRF,
                           "e2e_targets": dict(MONO_TARGETS)}
    with tempfile.TemporaryDirectory(prefix="digiteyes-bench-") as tmp:
        folders = {}
        for suffix, codec, crf in E2E_VIDEOS:
            folder, kb = _video_dataset(mono, frames, Path(tmp) / f"video{suffix}", codec, crf)
            folders[suffix] = folder
            out[f"kb_per_frame{suffix}"] = kb
            with open_sequence(folder) as seq:
                start = time.perf_counter()
                decoded = sum(1 for _ in seq)
                out[f"fps_decode{suffix}"] = decoded / (time.perf_counter() - start)

        def track_at(k: int) -> dict[str, Any]:
            run, with_outputs, log = _track_video(folders[""], k, False, Path(tmp) / f"k{k}")
            outcome = TrackOutcome(log, dict(run.stage_seconds), run.tracker_seconds,
                                   run.iterations, float("nan"))
            return accuracy_summary(truth, outcome) | _rates("fps", run, with_outputs)

        iterations, met, runs = choose_iterations(track_at)
        out |= {"fps_end_to_end_iterations": iterations, "targets_met": met,
                "e2e_runs": runs}
        out |= {key.replace("fps", "fps_end_to_end", 1): value
                for key, value in runs[iterations].items() if key.startswith("fps")}
        run, with_outputs, _ = _track_video(folders[""], iterations, True, Path(tmp) / "ov")
        out |= _rates("fps_end_to_end_overlay", run, with_outputs)
        for suffix, _, _ in E2E_VIDEOS[1:]:
            run, with_outputs, _ = _track_video(folders[suffix], iterations, False,
                                                Path(tmp) / f"run{suffix}")
            out |= _rates(f"fps_end_to_end{suffix}", run, with_outputs)
    return out


def accuracy_section(iteration_counts: Sequence[int], settings: Settings,
                     reuse: dict[tuple, RenderedSequence], known: dict[int, dict[str, Any]],
                     progress: bool) -> dict[int, dict[str, Any]]:
    """Section (c): every case x background x model, at each of ``iteration_counts``.

    Returns ``{iterations: {case: {background: {model: figures}}}}``. ``reuse`` holds
    already rendered sequences by (scenario, background, model); ``known`` maps an
    iteration count to the whole-hand stereo black exact figures when that run was
    already made (an ablation run), so it is not repeated."""
    out = {k: {case: {bg: {} for bg in BACKGROUNDS} for case in ACCURACY_CASES}
           for k in iteration_counts}
    scenarios = dict.fromkeys(case[0] for case in ACCURACY_CASES.values())
    for name in scenarios:
        scenario = build_scenario(name, seed=SEED, n_frames=settings.frames)
        for background in BACKGROUNDS:
            for model in MODELS:
                key = (name, background, model)
                sequence = reuse.get(key) or render_sequence(
                    scenario, background, model == "perturbed", progress=progress)
                for case, (scenario_name, cameras, pole) in ACCURACY_CASES.items():
                    if scenario_name != name:
                        continue
                    seq = sequence.cameras(cameras)
                    for k in iteration_counts:
                        if k in known and (case, background, model) == (
                                "whole-hand stereo", "black", "exact"):
                            out[k][case][background][model] = known[k]
                            continue
                        outcome = track_sequence(
                            seq, FeatureTrackerOptions(iterations_per_frame=k),
                            f"{case} {background} {model} {k} it", progress)
                        out[k][case][background][model] = accuracy_summary(seq, outcome, pole)
    return out


# --------------------------------------------------------------------------- run
@contextlib.contextmanager
def _one_thread() -> Iterator[str]:
    """Run OpenCV, numba's kernels (and NumPy's BLAS, if ``threadpoolctl`` is importable)
    on one thread; yields a note saying which."""
    with kernel_threads(opencv=1, numba_kernels=1):
        try:
            from threadpoolctl import threadpool_limits
        except ImportError:
            env = blas_info()["env"]
            if env:
                yield ("OpenCV and numba on 1 thread; BLAS threads as set before start: "
                       + ", ".join(f"{k}={v}" for k, v in env.items()))
            else:
                yield ("OpenCV and numba on 1 thread; BLAS threads not limited "
                       "(threadpoolctl not installed): set OPENBLAS_NUM_THREADS=1 before "
                       "starting for one core")
        else:
            with threadpool_limits(limits=1):
                yield "OpenCV, numba and BLAS on 1 thread (threadpoolctl)"


def run(json_path: str | None = None, quick: bool = False, *, progress: bool = True) -> dict:
    """Run the tracker benchmark, print its tables, optionally write JSON.

    Parameters
    ----------
    json_path : write the result to this JSON file if given.
    quick : a smoke run (30 frames per scenario, five ablations, one speed pass).
    progress : tqdm progress bars on stderr.

    Returns
    -------
    dict
        ``machine``, ``threads``, ``settings``; section (a): ``ms_per_iteration_mono``,
        ``ms_per_iteration_stereo``, ``per_iteration_mono``, ``per_iteration_stereo``
        (ms per Table 4.1 row), ``speedup_vs_thesis_mono``/``_stereo``,
        ``thesis_table_4_1_ms``; (b): ``fps_end_to_end``, ``fps_end_to_end_iterations``,
        ``fps_end_to_end_overlay``, ``fps_decode``, ``kb_per_frame``, ``e2e_runs``,
        ``targets_met`` (and the ``_crf12``, ``_ffv1`` videos); (c): ``accuracy``
        [case][background][model] -> per-run figures at ``accuracy_iterations`` (the
        end-to-end setting), ``accuracy_default_iterations`` the same at the tracker's
        default of 5 (None when that is the end-to-end setting); (d): ``ablations``
        [variant] -> per-run figures; (e): ``shading`` [lambert|flat] -> width bias and
        per-run figures with and without the width residuals. See the module docstring.
    """
    settings = QUICK if quick else FULL
    started = time.perf_counter()
    machine = machine_info()
    result: dict[str, Any] = {
        "benchmark": "tracker", "quick": quick, "machine": machine,
        "settings": {"seed": SEED, "noise_sigma": NOISE_SIGMA,
                     "perturb_link_length": PERTURB_LINK_LENGTH,
                     "frames_per_scenario": settings.frames or "scenario length",
                     "accuracy_targets": ACCURACY_TARGETS, "image": "640x480 grey"},
    }
    with _one_thread() as threads:
        result["threads"] = threads
        print("\n".join([f"tracker benchmark{' (quick)' if quick else ''}",
                         *machine_lines(machine), f"threads: {threads}", ""]), flush=True)
        whole = build_scenario("whole-hand", seed=SEED, n_frames=settings.frames)
        base = render_sequence(whole, progress=progress)

        result |= speed_section(base, settings, progress)
        print(format_speed(result) + "\n", flush=True)

        cores = numba.config.NUMBA_NUM_THREADS
        with kernel_threads(opencv=1, numba_kernels=cores):
            result["e2e_kernel_threads"] = cores
            result |= end_to_end_section(base, settings)
        print(format_end_to_end(result) + "\n", flush=True)
        iterations = result["fps_end_to_end_iterations"]

        result["ablations"] = ablation_section(base, settings, progress)
        print(format_ablations(result) + "\n", flush=True)

        counts = list(dict.fromkeys((iterations, DEFAULT_ITERATIONS)))
        known = {k: {key: v for key, v in run.items() if key != "options"}
                 for k in counts if (run := iterations_run(result["ablations"], k))}
        accuracy = accuracy_section(counts, settings, {("whole-hand", "black", "exact"): base},
                                    known, progress)
        result["accuracy_iterations"] = iterations
        result["accuracy"] = accuracy[iterations]
        result["accuracy_default_iterations"] = None if iterations == DEFAULT_ITERATIONS \
            else accuracy[DEFAULT_ITERATIONS]
        print(format_accuracy(result) + "\n", flush=True)

        result["shading"] = shading_section(settings, progress)
        print(format_shading(result), flush=True)
    result["wall_seconds"] = time.perf_counter() - started
    return emit(result, f"\nbenchmark wall time {result['wall_seconds']:.0f} s", json_path)


# --------------------------------------------------------------------------- tables
def _table(header: Sequence[str], rows: Sequence[Sequence[str]]) -> list[str]:
    """Aligned plain-text rows: first column left, the others right."""
    widths = [max(len(str(r[i])) for r in [header, *rows]) for i in range(len(header))]

    def line(row: Sequence[str]) -> str:
        return "  ".join([str(row[0]).ljust(widths[0]),
                          *(str(c).rjust(w) for c, w in zip(row[1:], widths[1:], strict=True))])

    return [line(header), "  ".join("-" * w for w in widths), *(line(r) for r in rows)]


def _f(value: float | None, fmt: str = ".1f") -> str:
    return "n/a" if value is None else f"{value:{fmt}}"


def format_speed(result: dict) -> str:
    """Section (a) as a table: Table 4.1 rows, thesis vs mono vs stereo."""
    thesis = result["thesis_table_4_1_ms"]
    mono, stereo = result["per_iteration_mono"], result["per_iteration_stereo"]
    rows = []
    labels = [("forward kinematics", "forward_kinematics"),
              ("feature detection", "feature_detection"),
              ("state estimation", "state_estimation"), ("  Jacobian", "jacobian"),
              ("  linear solve", "linear_solve"),
              ("other (prediction, bookkeeping)", "other"),
              ("overlay display", "overlay_display"), ("total", "total")]
    for label, key in labels:
        ref = thesis.get(key)
        cells = []
        for ours in (mono, stereo):
            value = ours.get(key)
            cells += [_f(value, ".2f"), f"{ref / value:.0f}x" if ref and value else ""]
        if key == "overlay_display":
            cells = ["not measured", "", "not measured", ""]
        rows.append([label, _f(ref), *cells])
    lines = [f"(a) ms per Gauss-Newton iteration, full hand (28 states), every link and tip, "
             f"{result['speed_iterations_per_frame']} iterations/frame, best of "
             f"{result['speed_passes']} pass(es) over {result['speed_frames']} whole-hand "
             "frames",
             *_table(["Table 4.1 row", "thesis 68040", "mono", "speed-up", "stereo",
                      "speed-up"], rows),
             f"features measured per iteration: mono {mono['features_per_iteration']:.0f}, "
             f"stereo {stereo['features_per_iteration']:.0f} (thesis: 35 residuals)",
             f"speed-up of the total without the thesis's overlay display (136.2 ms): mono "
             f"{result['speedup_vs_thesis_mono_without_overlay']:.0f}x, stereo "
             f"{result['speedup_vs_thesis_stereo_without_overlay']:.0f}x",
             f"shading prediction, once per frame and not in the rows above: mono "
             f"{mono['shading_per_frame']:.2f} ms, stereo {stereo['shading_per_frame']:.2f} ms "
             f"per frame; charged to the iterations the totals would be mono "
             f"{mono['total_with_shading']:.2f}, stereo {stereo['total_with_shading']:.2f} ms"]
    return "\n".join(lines)


RUN_COLUMNS = ("tip mm", "joint deg", "palm mm", "palm deg", "life", "lost", "ms/frame")


def _run_cells(r: dict) -> list[str]:
    return [_f(r["fingertip_err_mm_mean"], ".2f"), _f(r["joint_angle_err_deg_rms"], ".2f"),
            _f(r["palm_pos_err_mm_mean"], ".2f"), _f(r["palm_rot_err_deg_mean"], ".2f"),
            f"{r['track_life_frames']}/{r['frames']}", str(r["lost_frames"]),
            _f(r["ms_per_frame"])]


def format_ablations(result: dict) -> str:
    """Section (d) as a table."""
    rows = [[name, *_run_cells(r)] for name, r in result["ablations"].items()]
    target = ", ".join(f"{k} <= {v:g}" for k, v in ACCURACY_TARGETS.items())
    return "\n".join([
        "(d) ablations: whole-hand stereo, black cloth, exact model; mean fingertip error, "
        "joint-angle RMS, mean palm position / rotation error, track life, frames flagged "
        "lost, tracker ms per frame",
        *_table(["variant", *RUN_COLUMNS], rows),
        f"stereo targets: {target}"])


def format_end_to_end(result: dict) -> str:
    """Section (b) as two tables: the runs that chose the iterations, then the videos."""
    k = result["fps_end_to_end_iterations"]
    target = ", ".join(f"{key} <= {v:g}" for key, v in result["e2e_targets"].items())
    choice = [[str(n), _f(r["fps"]), _f(r["fps_tracker_only"]),
               _f(r["fingertip_err_mm_mean"], ".2f"), _f(r["joint_angle_err_deg_rms"], ".2f"),
               f"{r['track_life_frames']}/{r['frames']}",
               "yes" if meets_targets(r, result["e2e_targets"]) else "no"]
              for n, r in result["e2e_runs"].items()]
    rows = []
    for suffix, codec, crf in E2E_VIDEOS:
        label = "FFV1, lossless" if codec == "ffv1" else f"H.264 CRF {crf}"
        rows.append([f"{label}: decode only", _f(result[f"kb_per_frame{suffix}"]),
                     _f(result[f"fps_decode{suffix}"]), "", ""])
        keys = [("decode + track", "fps_end_to_end")]
        if not suffix:
            keys.append(("decode + track + overlay video", "fps_end_to_end_overlay"))
        for what, key in keys:
            rows.append([f"{label}: {what}", "", _f(result[f"{key}{suffix}"]),
                         _f(result[f"{key}{suffix}_with_outputs"]),
                         _f(result[f"{key}{suffix}_tracker_only"])])
    met = "meets" if result["targets_met"] else "NO choice meets"
    return "\n".join([
        f"(b) end to end: whole-hand seen by camera 0, {result['e2e_frames']} frames of video, "
        f"decoded and tracked as 'digiteyes track' does (numba kernels on "
        f"{result['e2e_kernel_threads']} threads, FFmpeg frame threads); iterations per "
        f"frame: the fewest whose run meets the one-camera targets ({target}) on the "
        f"H.264 CRF {result['e2e_crf']} video",
        *_table(["iterations", "frames/s (loop)", "tracker only", "tip mm", "joint deg",
                 "life", "meets"], choice),
        f"at {k} iteration(s)/frame ({met} the targets):",
        *_table(["video", "KB/frame", "frames/s (loop)", "incl. final plots", "tracker only"],
                rows),
        "loop: reading, tracking and logging every frame (the streaming rate); incl. final "
        "plots: the whole command, with the trajectory plots and 3D views written at the "
        "end"])


def format_accuracy(result: dict) -> str:
    """Section (c) as one table per iteration count: a row per case x background x model."""
    tables = [(result["accuracy_iterations"], result["accuracy"], "the end-to-end setting")]
    if result.get("accuracy_default_iterations") is not None:
        tables.append((DEFAULT_ITERATIONS, result["accuracy_default_iterations"],
                       "the tracker's default"))
    lines = [f"(c) accuracy; 'perturbed': images of a hand with link lengths off by up to "
             f"{100 * PERTURB_LINK_LENGTH:g} %, tracked with the nominal model; "
             "pole h: mean error of the 3D-mouse pole height"]
    for iterations, accuracy, label in tables:
        rows = []
        for case, by_background in accuracy.items():
            for background, by_model in by_background.items():
                for model, r in by_model.items():
                    pole = _f(r.get("pole_height_err_mm_mean"), ".2f") \
                        if "pole_height_err_mm_mean" in r else ""
                    rows.append([f"{case} / {background} / {model}", *_run_cells(r), pole])
        lines += ["", f"{iterations} iteration(s)/frame ({label})",
                  *_table(["case / background / model", *RUN_COLUMNS, "pole h mm"], rows)]
    return "\n".join(lines)


def format_shading(result: dict) -> str:
    """Section (e) as a table."""
    rows = []
    for shading, r in result["shading"].items():
        for label, name in (("corrected", "shading corrected"),
                            ("with_width", "uncorrected"),
                            ("without_width", "uncorrected, no width rows")):
            rows.append([f"{shading} / {name}",
                         _f(r["width_bias_px_mean"], "+.2f"),
                         _f(r["width_bias_px_link_rms"], ".2f"), *_run_cells(r[label])])
    return "\n".join([
        f"(e) one camera: whole-hand camera 0, black cloth, exact model, {DEFAULT_ITERATIONS} "
        "iterations/frame; Lambert shading (the default) vs flat shading (even skin, no "
        "darkening towards the silhouette); width bias: measured minus true link width at the "
        "true states (mean; RMS over links of the per-link means), px, without the "
        "correction",
        *_table(["shading / residuals", "width bias", "per link", *RUN_COLUMNS], rows)])
