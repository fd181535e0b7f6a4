"""The hand model fitted to a learned detector's keypoints, frame by frame (ours).

Neither seed has it: both track from image measurements of their own (edges, templates,
edge likelihoods) and leave the start to the user. On real footage that is where they
fail: on the real video (a right hand before a grey wall, docs/keypoint-tracker.md) the
feature tracker, started from a detection that puts every keypoint within
0.04 palm lengths of MediaPipe's, is 0.24 palm lengths off after three frames and 0.75
after nine, and is flagged lost in 7 of 621 frames while most frames are wrong.

This tracker leaves the image to a detector (:func:`~digiteyes.detect.pose.make_detector`
in video mode: MediaPipe follows its landmarks from frame to frame, one detector per
camera) and keeps what the model gives and the detector does not: the kinematic model's
joint limits, metric 3D in the camera frame from the hand's size, joint angles, several
cameras in one estimate. Per frame the 21 keypoints of every camera that sees the hand
are fitted (:func:`~digiteyes.detect.model_fit.fit_keypoints`, robust Gauss-Newton with
the joint prior) starting from the previous estimate, which keeps each finger's bend
towards or away from the camera where one view cannot tell; when that fit leaves a
keypoint beyond ``max_error_px``, a fit from scratch is tried too (:meth:`KeypointTracker.
_fit`: taken when it costs less without turning the palm over, or when the warm fit does
not explain the keypoints); a fit that moves the hand farther than a hand could move
(``max_jump``) is refused, and so is one beyond a single frame's bound that explains the
hand's silhouette no better than the held estimate. A frame in which no camera finds a hand,
or no fit explains the keypoints near the last estimate, holds the previous state and is
flagged lost.

**The hand's size from the start.** With one camera the keypoints fix the hand's size
times its depth, not each: a hand 10 % larger than the model is tracked 10 % too far
away. A start state that was *given* (a dataset's true state) fixes the depth, so on the
first frame after :meth:`KeypointTracker.reset` the hand's scale is fitted too, with the
palm's position held to the start's (``start_size``; :data:`START_POSITION_SIGMA_MM`),
and kept for the track; when the hand is not found in that frame the model's size stays
(later the hand has moved). An automatic start took its depth from the model's size, so
there the fit returns about that size, and ``digiteyes track`` turns the size fit off
for footage, whose start the images or the user's eye gave. States stay those of the
model file, in millimetres: the palm where the scaled hand's is, the angles its angles
(:meth:`~digiteyes.detect.model_fit.PoseFit.scaled_state`), and every result carries the
size (:attr:`~digiteyes.trackers.TrackResult.hand_scale`), with which the outputs and the
evaluation draw the hand (:func:`~digiteyes.kinematics.keypoints.hand_keypoints`).

**The hand's size on-line** (issue 16: "adapt on-line with a long time constant"). Two
or more cameras see the hand's depth, so every frame measures its size: after the frame's
fit at the current size, a short fit with the scale free starts from it
(:data:`SIZE_ITERATIONS`). The measurements of frames that are not lost, in which two
cameras or more found the hand, and whose
size fit explains the keypoints well (:data:`SIZE_MAX_RMS`) with a scale within
:data:`~digiteyes.detect.hand_size.HAND_SCALE_RANGE` are averaged, a running
mean of the first ``size_frames`` and then an exponential average with that time
constant (frames): the size settles within the first frames and then follows only what
persists, not a frame's bad detection. One camera cannot measure it (a hand ``s`` times
larger at ``s`` times the depth gives the same image), so there the size is the start's.
The same frames also measure the 15 finger segments, from the keypoints of a detector
that locates joints triangulated between the cameras
(:mod:`~digiteyes.detect.link_lengths`, as ``calibrate-hand`` does): their medians,
:attr:`KeypointTracker.measured_segments`, go into the model ``track`` writes at the
measured size; the track itself keeps one scale.

A fit that explains the keypoints can still be wrong (a detector that takes a hand-like
drawing or a back-lit hand for a hand labels its joints anyway), so the shared silhouette
rule (:mod:`digiteyes.trackers.silhouette_loss`, plain backdrops) judges every frame as
for the other trackers, and the re-detection after a loss is checked against it.
"""

from __future__ import annotations

import time
from collections.abc import Sequence
from dataclasses import dataclass, replace
from typing import ClassVar

import numpy as np

from digiteyes.camera import Rig
from digiteyes.detect.candidate import HandCandidate, HandDetector
from digiteyes.detect.hand21 import model_anchors
from digiteyes.detect.hand_size import HAND_SCALE_RANGE, model_hand_length
from digiteyes.detect.link_lengths import segment_lengths, triangulate
from digiteyes.detect.model_fit import FitOptions, KeypointObservation, PoseFit, fit_keypoints
from digiteyes.detect.pose import DETECTORS, make_detector
from digiteyes.detect.side import TRACKED_SIDE, SideFollower, pick_candidate
from digiteyes.errors import DigitEyesError
from digiteyes.features.slices import prepare_image
from digiteyes.kinematics import KinematicModel, forward_kinematics
from digiteyes.kinematics.rotations import quaternion_angle
from digiteyes.kinematics.scaling import model_unit_states
from digiteyes.kinematics.state import validate_state
from digiteyes.trackers.base import TrackResult, start_step
from digiteyes.trackers.loss_hold import LossHold, LossHoldOptions
from digiteyes.trackers.silhouette_loss import SilhouetteLoss, SilhouetteLossOptions

JUMP_FRAMES = 4
"""The frames without a fit that widen the jump bound of ``max_jump`` at most."""
START_POSITION_SIGMA_MM = 5.0
"""How closely the first frame's size fit holds the palm to the start's position (mm)."""
SEGMENT_FRAMES = 10
"""Frames that must measure a finger segment before :attr:`KeypointTracker.
measured_segments` reports the segments."""
SCRATCH_MAX_TURN_DEG = 30.0
"""A fit from scratch replaces a warm fit that explains the keypoints only when it turns
the palm by less than this (degrees; docs/keypoint-tracker.md)."""
SIZE_ITERATIONS = 3
"""Gauss-Newton iterations of a frame's size measurement (from the frame's fit)."""
SIZE_MAX_RMS = 2.0
"""A frame measures the hand's size only when its size fit reprojects the keypoints
within this many ``sigma_px`` (RMS): a hand-like drawing that the detector labels as a
hand is explained less well and would pull the size (docs/keypoint-tracker.md)."""


@dataclass(frozen=True)
class KeypointTrackerOptions(SilhouetteLossOptions, LossHoldOptions):
    """Settings of :class:`KeypointTracker` (with the silhouette rule's and the loss
    hold's).

    Attributes
    ----------
    detector : ``"auto"`` (MediaPipe when installed, else the classic detector),
        ``"mediapipe"``, ``"mediapipe-lite"`` or ``"classic"``.
    sigma_px : expected keypoint error of the detector, px (Huber scale of the fit).
    sigma_joint_deg : width of the fit's prior on each joint angle (deg).
    iterations : Gauss-Newton iterations of a fit at most (5: a warm start needs few;
        10 gave 0.2 mm less over the accuracy table at 10 % less speed on the real video,
        docs/keypoint-tracker.md).
    max_error_px : a fit explains the keypoints when at least ``min_explained`` of them
        reproject within this distance (px).
    min_explained : that fraction.
    motion_sigma_mm, motion_sigma_deg : the fit from the previous estimate is held to it
        by a prior on the change per frame, the palm's position (mm) and every angle, the
        palm's rotation included (deg): 20 mm and 20 degrees (since the twentieth
        session, when the fit began to converge, docs/keypoint-tracker.md, "A fit that
        converges"); None for either: no prior.
    max_jump : a fit whose keypoints' centroid moves more than this many hand lengths
        (wrist to middle fingertip) per frame since the last fit taken (counting at most
        :data:`JUMP_FRAMES` frames) is refused: a hand does not cross half a metre
        between frames, a detector that labels part of the hand (or something else)
        makes the fit do so. A fit beyond one frame's bound (after frames without a fit)
        is taken only when it explains the hand's silhouette better than the held
        estimate (where the silhouette rule is on and sees the hand). A hand that comes
        back far from where it was lost is taken up by the run loop's re-detection,
        which restarts the tracker.
    start_size : with one camera, fit the hand's scale on the first frame with the palm
        held at the start state's position (module docstring); False keeps the model's
        size.
    size_frames : with two or more cameras, the time constant (frames) of the on-line
        size (module docstring); None keeps the model's size.
    colour_foreground : off by default here (the silhouette rule's colour model over a
        textured backdrop): this tracker fits the detector's keypoints afresh every
        frame, so a re-detection after a silhouette flag brings back the same fit; on the
        real video (a grey wall the grey threshold refuses) the colour rule flagged 41
        frames whose track stayed on MediaPipe's hand (image gap median 0.06 palm lengths
        with the rule and without), cost 18 re-detections and took the loop from 64 to
        48 frames/s (docs/accuracy.md, "Over a textured backdrop"). ``--option
        colour_foreground=true`` turns it on.
    """

    detector: str = "auto"
    sigma_px: float = 4.0
    sigma_joint_deg: float = 45.0
    iterations: int = 5
    max_error_px: float = 25.0
    min_explained: float = 0.5
    max_jump: float = 0.5
    motion_sigma_mm: float | None = 20.0
    motion_sigma_deg: float | None = 20.0
    start_size: bool = True
    size_frames: float | None = 100.0
    colour_foreground: bool = False

    def __post_init__(self) -> None:
        for name in ("sigma_px", "sigma_joint_deg", "max_error_px", "max_jump"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, int | float) or not value > 0:
                raise ValueError(f"{name} must be a positive number, got {value!r}")
        if isinstance(self.iterations, bool) or not isinstance(self.iterations, int) \
                or self.iterations < 1:
            raise ValueError(f"iterations must be a positive integer, got {self.iterations!r}")
        if not 0 < self.min_explained <= 1:
            raise ValueError(f"min_explained must lie in (0, 1], got {self.min_explained!r}")
        for name in ("motion_sigma_mm", "motion_sigma_deg"):
            value = getattr(self, name)
            if value is not None and (isinstance(value, bool)
                                      or not isinstance(value, int | float) or not value > 0):
                raise ValueError(f"{name} must be a positive number or None, got {value!r}")
        if self.size_frames is not None and (
                isinstance(self.size_frames, bool)
                or not isinstance(self.size_frames, int | float) or not self.size_frames >= 1):
            raise ValueError(f"size_frames must be a number of frames >= 1 or None, got "
                             f"{self.size_frames!r}")
        if not isinstance(self.start_size, bool):
            raise ValueError(f"start_size must be true or false, got {self.start_size!r}")
        if self.detector not in DETECTORS:
            raise ValueError(f"detector must be one of {', '.join(DETECTORS)}, got "
                             f"{self.detector!r}")


@dataclass
class KeypointDetails:
    """What the keypoint tracker measured in one frame: per camera the candidate it
    fitted (None where the camera found no hand) and the fit's reprojection error per
    keypoint (n_cameras, 21) px (NaN where not detected)."""

    candidates: list[HandCandidate | None]
    reprojection_px: np.ndarray


class KeypointTracker:
    """The model fitted to detected keypoints every frame (module docstring)."""

    stages: ClassVar[tuple[str, ...]] = ("detection", "fit", "silhouette")
    follows_detector: ClassVar[bool] = True
    """It runs the detector on every frame: ``track`` adds no detection check."""

    def __init__(self, model: KinematicModel, rig: Rig,
                 options: KeypointTrackerOptions | None = None) -> None:
        self.model = model
        self.rig = rig
        self.options = options or KeypointTrackerOptions()
        self._anchors = model_anchors(model)  # raises unless the model has the 21 keypoints
        self._hand_length = model_hand_length(model)
        self._since_fit = 1
        opts = self.options
        motion = (None if opts.motion_sigma_mm is None or opts.motion_sigma_deg is None
                  else (float(opts.motion_sigma_mm), float(opts.motion_sigma_deg)))
        self._fit_options = FitOptions(sigma_px=opts.sigma_px,
                                       sigma_joint_deg=opts.sigma_joint_deg, fit_scale=False,
                                       iterations=opts.iterations, motion_sigma=motion,
                                       active_set=True)
        self.scale = 1.0
        """The hand's scale relative to the model file (the start's size fit, or the
        on-line size with several cameras)."""
        self.start_scale = 1.0
        """The scale the track started with (the start's size fit, else 1)."""
        self._size_pending = False
        self._size_measured = 0
        self._segments: list[np.ndarray] = []
        self._detectors: list = []
        self.silhouette_loss = SilhouetteLoss.from_options(model, rig, self.options)
        self.loss_hold = LossHold(self.options.hold_lost_frames)
        self.state: np.ndarray | None = None
        self._here = np.zeros((21, 3))
        """The 21 keypoints (mm) of the estimate the current frame starts from."""
        self._frame_index = 0

    def reset(self, initial_state: np.ndarray) -> None:
        """Start a new track from ``initial_state`` (n_q,); the detectors start afresh
        (a new video for MediaPipe's frame-to-frame following)."""
        self.state = validate_state(self.model, np.asarray(initial_state, dtype=float),
                                    normalize=True)
        for detector in self._detectors:
            getattr(detector, "close", lambda: None)()
        self._detectors = [SideFollower(self._make_detector) for _ in self.rig]
        self.silhouette_loss.reset()
        self.loss_hold.reset()
        self._frame_index = 0
        self._since_fit = 1
        self._set_scale(1.0)
        self.start_scale = 1.0
        self._size_measured = 0
        self._segments = []
        self._size_pending = self.options.start_size and len(self.rig) == 1

    def restart(self, state: np.ndarray) -> None:
        """Continue from ``state`` after a re-detection: the detectors keep following and
        the silhouette rule keeps its foreground; its baselines are taken anew."""
        self.state = validate_state(self.model, np.asarray(state, dtype=float),
                                    normalize=True)
        self.silhouette_loss.rebaseline()
        self.loss_hold.reset()
        self._since_fit = 1

    def step(self, frames: Sequence[np.ndarray]) -> TrackResult:
        """Detect the hand in every camera and fit the model to its keypoints."""
        start_total, timings = start_step(self, frames)
        start = time.perf_counter()
        self._here = here = self._keypoints_here()  # the estimate this frame starts from
        candidates = []
        for detector, image, camera in zip(self._detectors, frames, self.rig, strict=True):
            near = camera.project(here)  # the tracked hand's keypoints in this camera
            candidates.append(pick_candidate(detector.detect(image, camera, near),
                                             TRACKED_SIDE, near))
        timings["detection"] = time.perf_counter() - start
        start = time.perf_counter()
        observations = [KeypointObservation.of(c, camera)
                        for c, camera in zip(candidates, self.rig, strict=True) if c is not None]
        fit, iterations = None, 0
        if observations and self._size_pending:
            fit, iterations = self._fit_size(observations)
        self._size_pending = False  # the start's frame only: later, the hand has moved
        if fit is None and observations:
            fit, iterations = self._fit(observations)
        worse_silhouette = fit is not None and self._worse_silhouette(frames, fit)
        if worse_silhouette:
            fit = None
        size = None
        if fit is not None and self._adapts_size and len(observations) >= 2:
            size, size_iterations = self._measure_size(observations, fit)
            iterations += size_iterations
        timings["fit"] = time.perf_counter() - start
        predicted = self.state
        reprojection = np.full((len(self.rig), 21), np.nan)
        if fit is None:
            reason = ("no hand detected" if not observations else
                      "a fit far from the last estimate explains the hand's silhouette "
                      "worse than it" if worse_silhouette else
                      "no fit explains the keypoints near the last estimate")
            lost, rms = True, float("nan")
            self._since_fit += 1
        else:
            self._since_fit = 1
            self.state = fit.scaled_state()
            seen = [c is not None for c in candidates]
            reprojection[seen] = fit.reprojection_px
            errors = fit.reprojection_px[np.isfinite(fit.reprojection_px)]
            lost, reason, rms = False, "", float(np.sqrt(np.mean(errors ** 2)))
        finger_lost: dict[str, bool] = {}
        if self.options.silhouette_check:
            start = time.perf_counter()
            verdict = self.silhouette_loss.check([prepare_image(f) for f in frames],
                                                 self.state, predicted, colours=frames)
            timings["silhouette"] = time.perf_counter() - start
            finger_lost = verdict.finger_lost
            if verdict.reasons:
                reason = "; ".join(r for r in (reason, *verdict.reasons) if r)
                lost = True
        result = TrackResult(self.state.copy(), fit.cost if fit is not None else float("nan"),
                             rms, lost, reason, iterations, predicted, self._frame_index,
                             timings, finger_lost,
                             details=KeypointDetails(candidates, reprojection),
                             hand_scale=self.scale)
        if size is not None and not lost:
            self._adapt_size(size)
            self._measure_segments(candidates)
        self._frame_index += 1
        timings["total"] = time.perf_counter() - start_total
        return self.loss_hold.apply(result)

    def _make_detector(self, max_hands: int) -> HandDetector:
        return make_detector(self.options.detector, self.model, video=True, max_hands=max_hands)


    @property
    def _adapts_size(self) -> bool:
        return self.options.size_frames is not None and len(self.rig) >= 2

    def _measure_size(self, observations: list[KeypointObservation], fit: PoseFit
                      ) -> tuple[float | None, int]:
        """The hand's scale measured in this frame: a short fit with the scale free from
        the frame's ``fit`` (:data:`SIZE_ITERATIONS`); None when it does not explain the
        keypoints (or not within :data:`SIZE_MAX_RMS`) or leaves
        :data:`~digiteyes.detect.hand_size.HAND_SCALE_RANGE`. Also the iterations spent."""
        options = replace(self._fit_options, fit_scale=True, iterations=SIZE_ITERATIONS)
        try:
            measured = fit_keypoints(self.model, observations, options=options, q0=fit.q)
        except DigitEyesError:
            return None, 0
        low, high = HAND_SCALE_RANGE
        errors = measured.reprojection_px[np.isfinite(measured.reprojection_px)]
        if not (self._explains(measured) and low <= measured.scale <= high
                and np.sqrt(np.mean(errors ** 2)) <= SIZE_MAX_RMS * self.options.sigma_px):
            return None, measured.iterations
        return float(measured.scale), measured.iterations

    def _adapt_size(self, measured: float) -> None:
        """Move the scale towards a frame's measurement: the running mean of the first
        ``size_frames`` measurements, then an exponential average with that time constant
        (in the logarithm of the scale, so that 0.9 and 1/0.9 weigh alike)."""
        self._size_measured += 1
        gain = 1.0 / min(self._size_measured, float(self.options.size_frames))
        self._set_scale(float(np.exp((1.0 - gain) * np.log(self.scale)
                                     + gain * np.log(measured))))

    @property
    def measured_segments(self) -> np.ndarray | None:
        """The 15 finger segments (mm, :data:`~digiteyes.detect.link_lengths.SEGMENT_NAMES`
        order) measured on-line: per segment the median over the frames that measured
        the size; None before every segment was measured in :data:`SEGMENT_FRAMES`
        frames, or when the detectors do not locate joints."""
        if not self._segments:
            return None
        lengths = np.array(self._segments)
        if (np.isfinite(lengths).sum(axis=0) < SEGMENT_FRAMES).any():
            return None
        return np.nanmedian(lengths, axis=0)

    def _measure_segments(self, candidates: list[HandCandidate | None]) -> None:
        """Add this frame's finger segments, triangulated from the cameras that found the
        hand, when every detector locates joints."""
        if not all(getattr(d, "locates_joints", False) for d in self._detectors):
            return
        seen = [None if c is None else c.keypoints for c in candidates]
        self._segments.append(segment_lengths(triangulate(self.rig, seen)))

    def _set_scale(self, scale: float) -> None:
        self.scale = float(scale)
        self._fit_options = replace(self._fit_options, scale=self.scale)

    def _fit_size(self, observations: list[KeypointObservation]) -> tuple[PoseFit | None, int]:
        """The first frame's fit with the hand's scale free and the palm held to the start
        state's position; the scale is kept when the fit explains the keypoints and the
        scale lies in :data:`~digiteyes.detect.hand_size.HAND_SCALE_RANGE`. Returns that fit
        (None otherwise: the frame is fitted as any other) and its iterations."""
        options = replace(self._fit_options, fit_scale=True,
                          hold_position_mm=START_POSITION_SIGMA_MM)
        try:
            fit = fit_keypoints(self.model, observations, options=options, q0=self.state)
        except DigitEyesError:
            return None, 0
        low, high = HAND_SCALE_RANGE
        if not (self._explains(fit) and low <= fit.scale <= high):
            return None, fit.iterations
        self._set_scale(fit.scale)
        self.start_scale = self.scale
        return fit, fit.iterations

    def _fit(self, observations: list[KeypointObservation]) -> tuple[PoseFit | None, int]:
        """The fit from the previous estimate; when it leaves a keypoint beyond
        ``max_error_px``, also the fit from scratch, taken when the warm fit does not
        explain the keypoints near the last estimate, or when it costs less and turns the
        palm by less than :data:`SCRATCH_MAX_TURN_DEG` from the warm fit's (a warm start
        can leave a finger in a local minimum, tens of pixels off, while the rest
        explains the frame; a fit from scratch that turns the palm over is the other
        side of the ambiguity of a planar palm in one view, which the warm start
        settles); None when neither explains the keypoints. Also the solver iterations
        spent."""
        iterations, best = 0, None
        for q0 in (model_unit_states(self.model, self.state, self.scale), None):
            if best is not None and self._fits_every_keypoint(best):
                break
            try:
                fit = fit_keypoints(self.model, observations, options=self._fit_options, q0=q0)
            except DigitEyesError:
                continue
            iterations += fit.iterations
            if self._explains(fit) and self._near(fit) and (
                    best is None or (fit.cost < best.cost and self._palm_turn_deg(fit, best)
                                     < SCRATCH_MAX_TURN_DEG)):
                best = fit
        return best, iterations

    def _palm_turn_deg(self, a: PoseFit, b: PoseFit) -> float:
        """The angle between the palm orientations of two fits (degrees; 0 for a model
        whose palm has no pose base)."""
        k = self.model.base_state
        if k is None:
            return 0.0
        return float(np.degrees(quaternion_angle(a.q[k:k + 4], b.q[k:k + 4])))

    def _fits_every_keypoint(self, fit: PoseFit) -> bool:
        errors = fit.reprojection_px[np.isfinite(fit.reprojection_px)]
        return bool(np.all(errors <= self.options.max_error_px))

    def _jump_mm(self, fit: PoseFit) -> float:
        """How far ``fit`` moves the keypoints' centroid from the frame's start estimate
        (mm)."""
        return float(np.linalg.norm(fit.keypoints_world.mean(axis=0) - self._here.mean(axis=0)))

    def _near(self, fit: PoseFit) -> bool:
        """Whether ``fit`` keeps the hand within ``max_jump`` hand lengths per frame since
        the last fit taken (keypoints' centroid, mm; from the frame's start estimate)."""
        frames = min(self._since_fit, JUMP_FRAMES)
        return self._jump_mm(fit) <= self.options.max_jump * self._hand_length * frames

    def _worse_silhouette(self, frames: Sequence[np.ndarray], fit: PoseFit) -> bool:
        """Whether ``fit``, which moves the hand farther than one frame's ``max_jump``
        (possible after frames without a fit), explains the hand's silhouette
        (:meth:`~digiteyes.trackers.silhouette_loss.SilhouetteLoss.mismatch`) no better
        than the held estimate: then it is refused. On the webcam render a detection of
        part of the hand after six frames without one put the hand 364 mm farther away,
        and the track stayed there (docs/keypoint-tracker.md). False where the rule is off
        or sees no camera (a textured backdrop)."""
        if not self.options.silhouette_check or \
                self._jump_mm(fit) <= self.options.max_jump * self._hand_length:
            return False
        scores = self.silhouette_loss.mismatches(frames, [fit.scaled_state(), self.state],
                                                 colours=frames)
        return scores is not None and scores[0] >= scores[1]

    def _keypoints_here(self) -> np.ndarray:
        """The 21 keypoints (21, 3) mm of the current estimate, at the current size."""
        rows, points = self._anchors
        q = model_unit_states(self.model, self.state, self.scale)
        return self.scale * forward_kinematics(self.model, q).points(rows, points)

    def _explains(self, fit: PoseFit) -> bool:
        errors = fit.reprojection_px[np.isfinite(fit.reprojection_px)]
        return bool(errors.size and np.mean(errors <= self.options.max_error_px)
                    >= self.options.min_explained)
