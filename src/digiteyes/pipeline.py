"""Run a tracker over a stream of frames and write everything a user looks at afterwards.

This is the layer between :mod:`digiteyes.io` (frames in, logs out) and
:mod:`digiteyes.trackers` (which never touch files), shared by ``digiteyes track``,
``digiteyes demo`` and the tracker benchmark. Outputs in ``out_dir``:

* ``states.csv``: the state log (named columns, one row per frame, flushed per row);
* ``overlay.mp4``: every camera's image with what the tracker measured drawn on it (the
  feature tracker: T-shaped trackers, edge points, feature lines and residual vectors,
  report Fig. 4; :mod:`digiteyes.viz.track_overlay`), cameras side by side (H.264,
  :data:`OVERLAY_CRF`, :data:`OVERLAY_PRESET`);
* ``views/estimate-NNNNNN.png``: the estimated model rendered from another viewpoint
  (thesis Fig. 4.6) every ``views_every`` frames and at the last frame, drawn after the
  loop (a 30 ms rendering every 50 frames would stall a live stream);
* ``trajectory-palm.png`` and ``trajectory-joints.png``: the estimated palm pose and the
  index and thumb joint angles over time (thesis Figs. 4.7, 4.8);
* ``summary.json``: the tracker, the frame rate of the input (``fps``, which
  ``digiteyes export`` reads), frames, losses, timings per stage (the stages the tracker
  declares in ``Tracker.stages``; thesis Table 4.1 rows for the feature tracker).
  With a ``recover`` function, also the re-initialisations.

**Recovery.** With ``recover`` (e.g. :class:`digiteyes.detect.initialiser.AutoInitialiser`),
a frame the tracker flags lost is handed to it; when it returns a state (re-detection and
model fit) that explains the hand's silhouette better than the estimate
(:func:`recovered_state`; always, without a silhouette rule), that state replaces the
tracker's estimate for the frame, the tracker restarts
from it (:func:`~digiteyes.trackers.restart`: the feature tracker keeps its scene models,
so no refit), and the state log's ``reinitialised`` column is 1 for the frame (its ``lost`` flag
stays the tracker's). The recovery's time counts in the frame's ``time_s``.

**Frame sinks.** Every object of ``sinks`` (:class:`FrameSink`: the keypoint log, the
JSON-lines stream, the live window) receives each frame's images and result as soon as
it is tracked and is closed at the end.

Any :class:`~digiteyes.trackers.Tracker` runs through :func:`run_tracker`;
:func:`step_frames` is the bare loop (reset, then one timed ``step`` per frame) that the
benchmarks share.

Ctrl-C stops the loop; every frame tracked so far is already in ``states.csv`` and the
other outputs are written before the interruption is reported (``interrupted=True``).
"""

from __future__ import annotations

import time
from collections.abc import Callable, Iterable, Iterator, Sequence
from dataclasses import dataclass, field, replace
from itertools import chain
from pathlib import Path
from typing import Protocol

import numpy as np
from tqdm import tqdm

from digiteyes.camera import Rig
from digiteyes.io import StateLogWriter, VideoWriter
from digiteyes.io.safe_paths import atomic_write_json
from digiteyes.kinematics import KinematicModel
from digiteyes.kinematics.scaling import model_of_size
from digiteyes.trackers import Tracker, TrackResult, residual_unit, restart, sizes_hand, warm_up
from digiteyes.viz.model_view import write_model_png
from digiteyes.viz.track_overlay import overlay_image
from digiteyes.viz.trajectory import write_trajectory_plots

OVERLAY_CRF = 23
OVERLAY_PRESET = "veryfast"
"""H.264 settings of ``overlay.mp4``: x264's default quality and a fast preset, a video to
look at (about 2.5 KB and 5 ms per 640x480 frame, where the near-lossless CRF 12 of the
dataset videos at the medium preset took 60 KB and 45 ms)."""

Recover = Callable[[list[np.ndarray], float], "np.ndarray | None"]
"""``recover(images, hand_scale)``: the re-initialisation after a lost frame, from one
frame's images (rig order) a fresh state of a hand ``hand_scale`` times the size of the
tracker's model file (the lost frame's :attr:`~digiteyes.trackers.TrackResult.hand_scale`:
the size the tracker measured), or None when it finds no hand (e.g.
:class:`digiteyes.detect.initialiser.AutoInitialiser`)."""
Check = Callable[[int, Sequence[np.ndarray], np.ndarray], "str | None"]
"""``check(index, images, state)``: why the estimate of frame ``index`` is off (a loss
reason), or None (e.g. :class:`digiteyes.detect.check.DetectionCheck`)."""


class FrameSink(Protocol):
    """Receives every tracked frame (``reinitialised``: the state came from ``recover``)."""

    def write(self, index: int, images: Sequence[np.ndarray], result: TrackResult,
              reinitialised: bool) -> None: ...

    def close(self) -> None: ...


@dataclass
class TrackingRun:
    """What a run produced: counts, timings (seconds) and the files written.

    ``warm_up_seconds`` is the untimed first step that compiles (or loads) the kernels
    (:func:`digiteyes.trackers.warm_up`), kept out of every other figure;
    ``tracker_seconds`` sums the ``step`` calls; ``loop_seconds`` is the whole per-frame
    loop (reading frames, tracking, logging, overlays); ``wall_seconds`` adds the one-off
    outputs written at the end (plots, last 3D view, summary). ``fps`` is the frame rate
    of the input sequence (frames/s), not the tracker's speed (``tracker_fps``).
    ``hand_scale`` is the hand's size at the last frame relative to the model file, for
    trackers that fit it (:func:`~digiteyes.trackers.sizes_hand`; else None).
    """

    out_dir: Path
    tracker: str = ""
    fps: float | None = None
    stages: tuple[str, ...] = ()
    residual_unit: str = "px"
    n_frames: int = 0
    n_lost: int = 0
    first_lost_frame: int | None = None
    interrupted: bool = False
    warm_up_seconds: float = 0.0
    tracker_seconds: float = 0.0
    loop_seconds: float = 0.0
    wall_seconds: float = 0.0
    iterations: int = 0
    stage_seconds: dict[str, float] = field(default_factory=dict)
    finger_lost_frames: dict[str, int] = field(default_factory=dict)
    reinitialised_frames: list[int] = field(default_factory=list)
    files: dict[str, Path] = field(default_factory=dict)
    hand_scale: float | None = None

    @property
    def tracker_fps(self) -> float:
        """Frames per second of the tracker alone (``step`` calls), NaN before any frame."""
        return self.n_frames / self.tracker_seconds if self.tracker_seconds > 0 else float("nan")

    @property
    def loop_fps(self) -> float:
        """Frames per second of the per-frame loop: the streaming rate of the pipeline."""
        return self.n_frames / self.loop_seconds if self.loop_seconds > 0 else float("nan")

    @property
    def ms_per_iteration(self) -> float:
        """Mean milliseconds per solver iteration inside ``step`` (NaN for trackers that
        report no iterations)."""
        if not self.iterations:
            return float("nan")
        return 1e3 * self.tracker_seconds / self.iterations

    def to_json(self) -> dict:
        per_iteration = {k: 1e3 * v / self.iterations if self.iterations else None
                         for k, v in self.stage_seconds.items()}
        return {
            "tracker": self.tracker,
            "fps": self.fps,
            "stages": list(self.stages),
            "residual_unit": self.residual_unit,
            "frames": self.n_frames,
            "lost_frames": self.n_lost,
            "first_lost_frame": self.first_lost_frame,
            "interrupted": self.interrupted,
            "iterations": self.iterations,
            "warm_up_seconds": self.warm_up_seconds,
            "tracker_seconds": self.tracker_seconds,
            "loop_seconds": self.loop_seconds,
            "wall_seconds": self.wall_seconds,
            "tracker_fps": None if np.isnan(self.tracker_fps) else self.tracker_fps,
            "ms_per_iteration": None if np.isnan(self.ms_per_iteration)
            else self.ms_per_iteration,
            "ms_per_iteration_by_stage": per_iteration,
            "ms_per_frame_by_stage": {k: 1e3 * v / self.n_frames if self.n_frames else None
                                      for k, v in self.stage_seconds.items()},
            "lost_frames_per_finger": dict(self.finger_lost_frames),
            "reinitialisations": len(self.reinitialised_frames),
            "reinitialised_frames": list(self.reinitialised_frames),
            "hand_scale": self.hand_scale,
            "files": {k: str(v) for k, v in self.files.items()},
        }


def step_frames(tracker: Tracker, frames: Iterable[Sequence[np.ndarray]],
                initial_state: np.ndarray, first_index: int = 0,
                ) -> Iterator[tuple[int, Sequence[np.ndarray], TrackResult, float]]:
    """Reset ``tracker`` to ``initial_state`` and step it through ``frames`` (one list of
    images per time step, rig order); yields ``(index, images, result, seconds)`` per
    frame, ``index`` counted from ``first_index`` (the input's number of the first frame),
    ``seconds`` the wall time of the ``step`` call."""
    tracker.reset(np.asarray(initial_state, dtype=float))
    for index, images in enumerate(frames, start=first_index):
        images = list(images)
        start = time.perf_counter()
        result = tracker.step(images)
        yield index, images, result, time.perf_counter() - start


def recovered_state(tracker: Tracker, images: Sequence[np.ndarray], result: TrackResult,
                    recover: Recover | None) -> np.ndarray | None:
    """The state to continue from after frame ``result``: on a lost frame, the
    re-detection ``recover(images, result.hand_scale)`` (n_q,), a hand of the size the
    tracker measured, if it found one and, where the tracker has
    a silhouette rule with a fitted foreground (``tracker.silhouette_loss``), explains
    the hand's silhouette better than the estimate does
    (:meth:`~digiteyes.trackers.silhouette_loss.SilhouetteLoss.mismatch`): a fit to
    detected keypoints is often coarser than a track that is only briefly off. The
    tracker is then restarted from it (:func:`~digiteyes.trackers.restart`). None
    otherwise (the tracker goes on from its estimate)."""
    if not result.lost or recover is None:
        return None
    fresh = recover(list(images), result.hand_scale)
    if fresh is None:
        return None
    fresh = np.asarray(fresh, dtype=float)
    rule = getattr(tracker, "silhouette_loss", None)
    if rule is not None:
        now = rule.mismatch(images, result.state, colours=images)
        new = rule.mismatch(images, fresh, colours=images)
        if now is not None and new is not None and new >= now:
            return None
    restart(tracker, fresh)
    return fresh


def run_tracker(
    tracker: Tracker,
    model: KinematicModel,
    rig: Rig,
    frames: Iterable[Sequence[np.ndarray]],
    initial_state: np.ndarray,
    out_dir: str | Path,
    *,
    fps: float = 10.0,
    total: int | None = None,
    overlay: bool = True,
    views_every: int = 50,
    view: str = "bottom",
    progress: bool = True,
    tracker_name: str | None = None,
    warm: bool = True,
    recover: Recover | None = None,
    sinks: Sequence[FrameSink] = (),
    first_index: int = 0,
    check: Check | None = None,
) -> TrackingRun:
    """Track ``frames`` (one list of images per time step, rig order) from
    ``initial_state`` with any :class:`~digiteyes.trackers.Tracker` and write the outputs
    listed in the module docstring. ``tracker_name`` goes into ``summary.json`` (default:
    the tracker's class name). With ``warm`` the tracker first steps once on the first
    frame, untimed, and is reset (:func:`digiteyes.trackers.warm_up`): compiling the
    kernels on a first run stays out of the figures. ``recover`` and ``sinks``: see the
    module docstring. ``first_index`` numbers the first frame in every output (the input's
    own number of that frame, e.g. where an automatic start found the hand). ``check``
    judges each frame the tracker did not flag; a reason it gives marks the frame lost
    (with that reason), and the recovery follows as for the tracker's own losses."""
    out = Path(out_dir)
    (out / "views").mkdir(parents=True, exist_ok=True)
    stages = tuple(tracker.stages)
    run = TrackingRun(out, tracker=tracker_name or type(tracker).__name__, fps=float(fps),
                      stages=stages, residual_unit=residual_unit(tracker),
                      stage_seconds=dict.fromkeys(stages, 0.0))
    states: list[np.ndarray] = []
    viewed: list[tuple[int, np.ndarray, float]] = []  # (frame, state, hand scale) of views/
    frames = iter(frames)
    first = next(frames, None)
    if first is not None:
        first = list(first)
        frames = chain([first], frames)
        if warm:
            run.warm_up_seconds = warm_up(tracker, first, initial_state)
    started = time.perf_counter()
    log_path = out / "states.csv"
    video = VideoWriter(out / "overlay.mp4", fps, codec="h264", crf=OVERLAY_CRF,
                        preset=OVERLAY_PRESET) if overlay else None
    bar = tqdm(frames, total=total, unit="frame", desc="tracking", disable=not progress)
    try:
        sized = sizes_hand(tracker)
        with StateLogWriter(log_path, model, reinitialised=recover is not None,
                            hand_scale=sized) as log:
            for index, images, result, seconds in step_frames(tracker, bar, initial_state,
                                                                 first_index):
                start = time.perf_counter()
                if check is not None and not result.lost:
                    reason = check(index, images, result.state)
                    if reason:
                        result = replace(result, lost=True, loss_reason=reason)
                fresh = recovered_state(tracker, images, result, recover)
                if fresh is not None:  # a fit of a hand of the size the tracker measured
                    result = replace(result, state=fresh)
                    run.reinitialised_frames.append(index)
                seconds += time.perf_counter() - start
                log.append(index, result.state, time_s=seconds, lost=result.lost,
                           residual_rms_px=result.residual_rms_px,
                           iterations=result.iterations, reinitialised=fresh is not None,
                           hand_scale=result.hand_scale)
                _account(run, result, index, seconds)
                if sized:
                    run.hand_scale = float(result.hand_scale)
                for sink in sinks:
                    sink.write(index, images, result, fresh is not None)
                states.append(result.state)
                if video is not None:
                    video.write(overlay_image(images, result, rig, model))
                if views_every and index % views_every == views_every - 1:
                    viewed.append((index, result.state, result.hand_scale))
                bar.set_postfix(rms=f"{result.residual_rms_px:.2f} {run.residual_unit}",
                                lost=run.n_lost, refresh=False)  # shown at tqdm's own pace
    except KeyboardInterrupt:
        run.interrupted = True
    finally:
        run.loop_seconds = time.perf_counter() - started
        bar.close()
        for sink in sinks:
            sink.close()
        if video is not None:
            video.close()
            if video.n_written:
                run.files["overlay"] = video.path
    run.files["states"] = log_path
    if states:
        last = first_index + run.n_frames - 1
        if not (views_every and last % views_every == views_every - 1):
            viewed.append((last, states[-1], run.hand_scale or 1.0))
        for index, state, scale in viewed:  # after the loop: no stall in a live stream
            _write_view(model_of_size(model, scale), state, out, index, view, run,
                        rig.mirrored)
        run.files.update(write_trajectory_plots(model, np.array(states), out))
    run.wall_seconds = time.perf_counter() - started
    summary = out / "summary.json"
    atomic_write_json(summary, run.to_json())
    run.files["summary"] = summary
    return run


def _account(run: TrackingRun, result: TrackResult, index: int, seconds: float) -> None:
    run.n_frames += 1
    run.tracker_seconds += seconds
    run.iterations += result.iterations
    for stage in run.stages:
        run.stage_seconds[stage] += result.timings.get(stage, 0.0)
    for finger, lost in result.finger_lost.items():
        run.finger_lost_frames[finger] = run.finger_lost_frames.get(finger, 0) + bool(lost)
    if result.lost:
        run.n_lost += 1
        if run.first_lost_frame is None:
            run.first_lost_frame = index


def _write_view(model: KinematicModel, q: np.ndarray, out: Path, index: int, view: str,
                run: TrackingRun, mirrored: bool = False) -> None:
    path = write_model_png(model, q, out / "views" / f"estimate-{index:06d}.png", view=view,
                           width=480, height=360, mirrored=mirrored)
    run.files[f"view-{index:06d}"] = path
