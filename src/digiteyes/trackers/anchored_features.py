"""The feature tracker anchored by a learned detector's keypoints (ours): ``features+keypoints``.

The DigitEyes feature tracker (report Sec. 4, thesis Sec. 4.3) aligns every link to the
image's edges to about a pixel, but it is local: a finger that slides onto its
neighbour's edge, or curls out of sight, stays wrong, and the residual does not show it
(docs/accuracy.md: on the flesh hand its median fingertip error is 4-5 mm on the
two-camera rigs while its mean is 8-15 mm). The keypoint tracker
(:mod:`digiteyes.trackers.keypoint_tracker`) does not lose the hand, because a detector
(MediaPipe in video mode) finds every finger in every frame, but it fits the detector's
keypoints, which sit a few millimetres off the model's joints, and is no more precise
than they are.

This tracker puts both measurements into one least-squares problem. Every Gauss-Newton
iteration of the feature tracker (Rehg eq. 2.22) stacks, below the line and tip residuals
(eq. 2.17-2.21, re-measured at the iterate), the reprojection residuals of the 21
keypoints the detector found in each camera that sees the hand (:class:`KeypointRows`):
``sqrt(c_k) (pi(p_k(q)) - u_k) / keypoint_sigma_px`` for keypoint ``k`` of confidence
``c_k``, with the analytic Jacobian ``d pi / d p`` (eq. 2.5-2.8) times the point Jacobian of
the kinematic chain (eq. 2.14-2.16). A keypoint off by ``keypoint_sigma_px`` (MediaPipe's
typical error, the keypoint fit's ``sigma_px``) thus weighs as a feature off by one pixel:
where a link's edges are seen they decide its place, and the keypoints hold every finger
near the detector's hand where the edges are ambiguous or hidden. Everything else (the
hand's size from a known start, the shading correction, the silhouette loss rule, the
loss hold, restarts) is the feature tracker's, but for one rule of its own: a frame in
which a camera's detection lies farther from the estimate than the gate lets through
(``anchor_max_gap``) is flagged lost (the detection check's rule, :mod:`digiteyes.detect.
check`, on the palm), so the run loop re-detects, unless another camera's detection
agrees with the estimate (then the one beyond the gate is the detector's error: on our
drawing's two-camera rig MediaPipe labelled part of the hand in one view in 13 of 60
frames of a track 0.2-2.5 mm off); ``track`` adds no detection check.

Needs a detector that locates joints (``mediapipe`` or ``mediapipe-lite``, the optional
extra); a camera in which it finds no hand contributes features only.
"""

from __future__ import annotations

import time
from collections.abc import Sequence
from dataclasses import dataclass, replace
from typing import ClassVar

import numpy as np

from digiteyes.camera import Rig
from digiteyes.detect.candidate import HandCandidate, HandDetector
from digiteyes.detect.check import palm_gap
from digiteyes.detect.hand21 import model_anchors
from digiteyes.detect.mediapipe_detector import INSTALL_HINT, mediapipe_available
from digiteyes.detect.pose import make_detector
from digiteyes.detect.side import TRACKED_SIDE, SideFollower, pick_candidate
from digiteyes.errors import DigitEyesError
from digiteyes.features.appearance import ShadingModel
from digiteyes.kinematics import KinematicModel, Kinematics, forward_kinematics, point_jacobian
from digiteyes.kinematics.step_form import StepForm
from digiteyes.trackers.base import TrackResult
from digiteyes.trackers.feature_tracker import FeatureTracker, FeatureTrackerOptions, MoreRows

ANCHOR_DETECTORS = ("mediapipe", "mediapipe-lite")
"""Detectors whose keypoints are joints (the classic detector's are rough guesses)."""


@dataclass(frozen=True)
class AnchoredFeatureOptions(FeatureTrackerOptions):
    """Settings of :class:`AnchoredFeatureTracker`: the feature tracker's, and

    detector : the keypoint detector, one of :data:`ANCHOR_DETECTORS` (video mode).
    keypoint_sigma_px : a detected keypoint's expected error (px); its residual is
        divided by it, so a keypoint that far off weighs as a feature off by one pixel.
    hold_lost_frames : 0 (judge each frame alone, as every tracker by default): the
        detector finds a lost finger again in the next frame, as a particle filter can.
    anchor_max_gap : a camera's detection is used only when its palm keypoints lie
        within this many palm lengths of the estimate's on average
        (:func:`~digiteyes.detect.check.palm_gap`; the detection check's ``max_gap``): a
        detector that labels part of the hand, or something else, as a hand would drag
        the model away (one camera: in depth), and the features could not bring it back.
    """

    detector: str = "mediapipe"
    keypoint_sigma_px: float = 4.0
    anchor_max_gap: float = 0.5

    def __post_init__(self) -> None:
        super().__post_init__()
        if self.detector not in ANCHOR_DETECTORS:
            raise ValueError(f"detector must be one of {', '.join(ANCHOR_DETECTORS)} (a "
                             f"detector that locates joints), got {self.detector!r}")
        for name in ("keypoint_sigma_px", "anchor_max_gap"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, int | float) \
                    or not value > 0:
                raise ValueError(f"{name} must be a positive number, got {value!r}")


class KeypointRows:
    """The residual rows of detected keypoints (module docstring), one block of 42 rows
    per camera with a detection, for :class:`~digiteyes.trackers.feature_tracker.
    FeatureProblem`.

    Parameters
    ----------
    anchors : the tracked model's 21 keypoints, shape-frame rows (21,) and points (21, 3)
        mm (:func:`model_anchors`).
    rig : the cameras.
    candidates : per camera the detected hand, or None.
    sigma_px : the keypoints' expected error, px.
    form : the step form of the Jacobian's columns (the tracker's).
    """

    def __init__(self, anchors: tuple[np.ndarray, np.ndarray], rig: Rig,
                 candidates: Sequence[HandCandidate | None], sigma_px: float,
                 form: StepForm | str) -> None:
        self.rows, self.points = anchors
        self.form = form
        self.cameras = [camera for camera, c in zip(rig, candidates, strict=True)
                        if c is not None]
        self.targets = [np.asarray(c.keypoints, dtype=float) for c in candidates
                        if c is not None]
        self.weights = [np.sqrt(np.clip(np.asarray(c.keypoint_confidence, dtype=float),
                                        0.0, 1.0)) / sigma_px
                        for c in candidates if c is not None]

    def __len__(self) -> int:
        """The number of residual rows."""
        return 42 * len(self.cameras)

    def __call__(self, kin: Kinematics, jacobian: bool) -> tuple[np.ndarray, np.ndarray | None]:
        """Residuals (42 C,) at the kinematics ``kin`` and their Jacobian (42 C, n_v)."""
        if jacobian:
            p_world, J_point = point_jacobian(kin, self.rows, self.points, self.form)
        else:
            p_world, J_point = kin.points(self.rows, self.points), None
        rs, Js = [], []
        for camera, target, weight in zip(self.cameras, self.targets, self.weights,
                                          strict=True):
            pixels, J_pixel = camera.project_with_jacobian(p_world, jacobian)
            rs.append((weight[:, None] * (pixels - target)).ravel())
            if jacobian:
                J = np.einsum("kab,kbn->kan", J_pixel, J_point)
                Js.append((weight[:, None, None] * J).reshape(-1, J.shape[-1]))
        n_v = 0 if J_point is None else J_point.shape[-1]
        r = np.concatenate(rs) if rs else np.zeros(0)
        if not jacobian:
            return r, None
        return r, np.concatenate(Js) if Js else np.zeros((0, n_v))


class AnchoredFeatureTracker(FeatureTracker):
    """The feature tracker with a detector's keypoints in every solve (module docstring)."""

    stages: ClassVar[tuple[str, ...]] = (*FeatureTracker.stages, "detection")
    follows_detector: ClassVar[bool] = True
    """It runs the detector on every frame: ``track`` adds no detection check."""
    options: AnchoredFeatureOptions

    def __init__(self, model: KinematicModel, rig: Rig,
                 options: AnchoredFeatureOptions | None = None) -> None:
        options = options or AnchoredFeatureOptions()
        model_anchors(model)  # raises unless the model has the 21 keypoints
        if not mediapipe_available():
            raise DigitEyesError(f"tracker features+keypoints: {INSTALL_HINT}")
        super().__init__(model, rig, options)
        self._detectors: list[SideFollower] = []
        self._off_detection: list[str] = []
        self.last_candidates: list[HandCandidate | None] = []
        """The hand each camera's detector found in the last frame and the solve used
        (None: none, or one too far from the estimate, ``anchor_max_gap``)."""

    def reset(self, initial_state: np.ndarray, shading: ShadingModel | None = None) -> None:
        """Start a new track (the feature tracker's reset); the detectors start afresh (a
        new video for MediaPipe's frame-to-frame following)."""
        super().reset(initial_state, shading)
        for detector in self._detectors:
            getattr(detector, "close", lambda: None)()
        self._detectors = [SideFollower(self._make_detector) for _ in self.rig]

    def step(self, frames: Sequence[np.ndarray]) -> TrackResult:
        """The feature tracker's step with the keypoints' rows in every solve; lost, too,
        when the cameras' detections lie beyond the gate and none agrees with the
        estimate (module docstring)."""
        result = super().step(frames)
        if not self._off_detection:
            return result
        reason = f"off the detected hand ({', '.join(self._off_detection)})"
        return replace(result, lost=True, loss_reason="; ".join(
            r for r in (result.loss_reason, reason) if r))

    def _make_detector(self, max_hands: int) -> HandDetector:
        return make_detector(self.options.detector, self.model, video=True,
                             max_hands=max_hands)

    def _more_rows(self, frames: Sequence[np.ndarray], timings: dict[str, float]
                   ) -> MoreRows | None:
        """Detect the hand in every camera, near the current estimate's keypoints, and
        return its keypoints' rows (None when no camera finds it)."""
        start = time.perf_counter()
        anchors = model_anchors(self.model)
        here = forward_kinematics(self.model, self.state).points(*anchors)
        candidates, self._off_detection = [], []
        for detector, image, camera in zip(self._detectors, frames, self.rig, strict=True):
            near = camera.project(here)
            found = pick_candidate(detector.detect(image, camera, near), TRACKED_SIDE, near)
            gap = None if found is None else palm_gap(near, found.keypoints)
            if gap is not None and gap > self.options.anchor_max_gap:
                self._off_detection.append(camera.name)
                found = None
            candidates.append(found)
        agreed = any(c is not None for c in candidates)
        if agreed:
            # another camera's detection agrees with the estimate: the one beyond the
            # gate is taken for the detector's error, not the track's (a camera alone
            # cannot tell them apart, and its disagreement is flagged)
            self._off_detection = []
        self.last_candidates = candidates
        timings["detection"] += time.perf_counter() - start
        if not agreed:
            return None
        return KeypointRows(anchors, self.rig, candidates, self.options.keypoint_sigma_px,
                            self.parameterisation.form)


__all__ = ["ANCHOR_DETECTORS", "AnchoredFeatureOptions", "AnchoredFeatureTracker",
           "KeypointRows"]
