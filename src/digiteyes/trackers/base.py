"""The interface every tracker shares (DESIGN.md Sec. 5): ``reset`` then ``step`` per frame.

Every tracker fills the core of :class:`TrackResult` (state, cost, residual RMS, track
loss, iterations, prediction, frame index, timings) and puts what only it measured into
``details``: one object of a type of its own (:class:`~digiteyes.trackers.feature_tracker.
FeatureDetails` for the feature tracker). The run loop, the state log, ``summary.json``,
``evaluate`` and ``bench`` read the core only; overlays dispatch on the type of
``details`` (:mod:`digiteyes.viz.track_overlay`).
"""

from __future__ import annotations

import time
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any, ClassVar, Protocol, runtime_checkable

import numpy as np

from digiteyes.camera import Rig
from digiteyes.errors import StateError
from digiteyes.kinematics import KinematicModel


@dataclass
class TrackResult:
    """What a tracker reports for one frame.

    Attributes
    ----------
    state : (n_q,) estimated state (mm, rad, unit quaternion).
    cost : the tracker's final cost for the frame (for least-squares trackers
        ``sum_i rho(r_i)``, px^2; NaN when it has none).
    residual_rms_px : root mean square of the final residual vector (NaN when nothing was
        measured), in the tracker's :data:`residual_unit`: pixels for the feature and
        particle trackers, grey levels of the filtered image for the template trackers
        (the name keeps the log files' column).
    lost : the track-loss rules fired in this frame, or it falls within the tracker's hold
        after such a frame (:mod:`digiteyes.trackers.loss_hold`); tracking goes on
        regardless.
    loss_reason : why (``""`` when not lost; several reasons are joined by ``"; "``).
    iterations : solver iterations (or particle generations) spent on this frame.
    predicted_state : (n_q,) the prediction the tracker started from.
    frame_index : frames stepped since the last :meth:`Tracker.reset` (0 for the first).
    timings : seconds per stage for this frame, keyed by the tracker's
        :attr:`Tracker.stages` (plus ``"total"``, the whole ``step`` call).
    finger_lost : finger name -> lost flag for trackers that judge fingers one by one
        (divide and conquer); empty when the tracker judges the hand as a whole.
    details : what this tracker type measured (its own dataclass; overlays dispatch on
        its type). ``None`` when the tracker reports nothing more.
    hand_scale : the size of the hand the state poses, relative to the model file (1: the
        model's hand; the keypoint tracker's fitted size). ``state``'s translation is the
        palm's position in mm; its points are those of
        :func:`~digiteyes.kinematics.keypoints.hand_keypoints` at this scale.
    """

    state: np.ndarray
    cost: float
    residual_rms_px: float
    lost: bool
    loss_reason: str
    iterations: int
    predicted_state: np.ndarray | None = None
    frame_index: int = 0
    timings: dict[str, float] = field(default_factory=dict)
    finger_lost: Mapping[str, bool] = field(default_factory=dict)
    details: Any = None
    hand_scale: float = 1.0


@runtime_checkable
class Tracker(Protocol):
    """One interface for every tracker. Trackers never read files; ``io/`` and the CLI do.

    ``frames`` holds one image per camera of the tracker's rig, in rig order; ``step``
    checks them against the rig (the one check per frame) and raises
    :class:`~digiteyes.errors.CameraError` when they do not fit.

    Attributes
    ----------
    stages : names of the timing stages the tracker reports in
        :attr:`TrackResult.timings` (``"total"`` is always there too and not listed).
    model, rig : the kinematic model and the cameras it tracks with.

    A tracker whose residual is not in pixels says so in a class attribute
    ``residual_unit`` (read by :func:`residual_unit`; ``"px"`` when absent).
    """

    stages: ClassVar[tuple[str, ...]]
    model: KinematicModel
    rig: Rig

    def reset(self, initial_state: np.ndarray) -> None:
        """Start a new track from ``initial_state`` (n_q,)."""
        ...

    # Optional: ``restart(state)`` continues the same scene from ``state`` after a
    # re-detection, keeping what the tracker learned about the scene; the run loop calls
    # it when the tracker has it, else ``reset`` (:func:`restart`).

    def step(self, frames: Sequence[np.ndarray]) -> TrackResult:
        """Estimate the state for the next set of frames."""
        ...


def start_step(tracker: Tracker, frames: Sequence[np.ndarray]) -> tuple[float, dict[str, float]]:
    """The common start of a least-squares tracker's ``step``: raises
    :class:`~digiteyes.errors.StateError` before :meth:`Tracker.reset` (no ``state``) and
    :class:`~digiteyes.errors.CameraError` when ``frames`` do not fit the rig; returns
    the step's start time (``time.perf_counter``) and its timings, every stage and
    ``"total"`` at 0 s."""
    if getattr(tracker, "state", None) is None:
        raise StateError("the tracker has no state: call reset(initial_state) first")
    started = time.perf_counter()
    tracker.rig.check_images(frames)
    return started, dict.fromkeys((*tracker.stages, "total"), 0.0)


def residual_unit(tracker: Tracker) -> str:
    """The unit of ``tracker``'s :attr:`TrackResult.residual_rms_px`: its
    ``residual_unit`` attribute, ``"px"`` when it has none."""
    return str(getattr(tracker, "residual_unit", "px"))


def sizes_hand(tracker: Tracker) -> bool:
    """Whether ``tracker`` fits the hand's size (it has a ``scale`` attribute, the size of
    the hand its states pose, relative to the model file): its results carry
    :attr:`TrackResult.hand_scale`, and its state logs a ``hand_scale`` column."""
    return getattr(tracker, "scale", None) is not None


def restart(tracker: Tracker, state: np.ndarray) -> None:
    """Continue ``tracker`` from ``state`` after a re-detection: its ``restart`` when it has
    one (it keeps what it learned about the scene), else :meth:`Tracker.reset`."""
    getattr(tracker, "restart", tracker.reset)(np.asarray(state, dtype=float))


def warm_up(tracker: Tracker, images: Sequence[np.ndarray], initial_state: np.ndarray
            ) -> float:
    """Step ``tracker`` once on ``images`` from ``initial_state`` and discard the result
    (compiles or loads every kernel the tracker uses); the caller resets the tracker
    before tracking. Returns the seconds it took."""
    start = time.perf_counter()
    tracker.reset(np.asarray(initial_state, dtype=float))
    tracker.step(list(images))
    return time.perf_counter() - start
