"""A tracker's start from the images alone: detect the hand, fit the model, return a state.

:class:`AutoInitialiser` is what ``digiteyes track --init auto`` runs on the first frames
and, after a frame the tracker flags lost, again (the recovery of
:func:`digiteyes.pipeline.run_tracker`). It calls :func:`~digiteyes.detect.pose.estimate_pose`
(the detector in every camera, then :func:`~digiteyes.detect.model_fit.fit_keypoints`) with
the hand scale held at the model's (``fit_scale=False``), so the state belongs to the very
model the tracker uses (a personal model from ``calibrate-hand`` sets the size). When the
joint fit to all cameras does not match the detections, the best fit to one camera alone
is taken (the tracker, seeing every camera, corrects its depth).

With two or more cameras the keypoints also say how large the hand is: after the start,
:meth:`AutoInitialiser.size_hand` fits the start frame's detections again with the scale
free and, when that fit matches them and the size is clearly not the model's, moves the
initialiser (and the run) to a model of that size (docs/initialisation.md, "The hand's
size from two cameras").
"""

from __future__ import annotations

import time
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass, field, replace
from itertools import chain

import numpy as np

from digiteyes.camera import Rig
from digiteyes.detect.hand_size import HAND_SCALE_RANGE, palm_scale
from digiteyes.detect.model_fit import FitOptions, KeypointObservation, PoseFit, fit_keypoints
from digiteyes.detect.pose import PoseResult, estimate_pose, make_detector
from digiteyes.errors import DatasetError, DigitEyesError
from digiteyes.kinematics import KinematicModel
from digiteyes.kinematics.scaling import scaled_model

MAX_HANDS = 2
"""Hands the detector returns at most, so that the one of the tracked side can be picked
when a second hand is in view (:mod:`digiteyes.detect.side`)."""
MIN_DETECTED_FRACTION = 0.5
"""A fit is accepted when at least this fraction of the 21 keypoints reprojects within
``max_error_px`` (a detector's wrong labelling leaves most keypoints far off)."""
SIZE_FIT_MAX_PX = 8.0
""":meth:`AutoInitialiser.size_hand` takes a size only from a fit whose median keypoint
reprojection error is at most this (px): twice the detector error the fit expects
(:attr:`~digiteyes.detect.model_fit.FitOptions.sigma_px`). Measured on the first frames of
the two-camera desk renders (``digiteyes bench auto-start``): MediaPipe's keypoints on the
flesh hand fit within 2.9-5.0 px and give sizes within 0.03 of the truth; the classic
detector's fit at 10.9 px and more with sizes up to 0.33 off."""
MIN_SIZE_CHANGE = 0.05
"""A measured size within this of 1 keeps the model's (the same dead band as the first
frame's feature measurement, :data:`digiteyes.trackers.feature_size.DEAD_BAND`): a hand of
the model's size measured 0.968-1.004 in those renders."""


@dataclass
class AutoInitialiser:
    """Detect and fit on demand; callable as a :data:`digiteyes.pipeline.Recover`.

    Attributes
    ----------
    model, rig : the tracker's model and cameras.
    detector : ``"auto"`` (MediaPipe when installed, with the classic detector for the
        images where MediaPipe finds no hand,
        :class:`~digiteyes.detect.fallback.FallbackDetector`; else classic), or any name
        of :data:`~digiteyes.detect.pose.DETECTORS` for that detector alone.
    max_error_px : reprojection error (px) a keypoint of an accepted fit stays within.
    side : the side of the hand to fit where the images show several
        (:mod:`digiteyes.detect.side`; in the images given, which a left hand's run
        mirrors: ``"right"`` once the side is known); None (default) takes any, the most
        confident.
    calls, found : how many times it ran and found a hand; ``seconds`` their total (s).
    last : the last :class:`PoseResult` (None before the first call).
    """

    model: KinematicModel
    rig: Rig
    detector: str = "auto"
    max_error_px: float = 25.0
    side: str | None = None
    calls: int = 0
    found: int = 0
    seconds: float = 0.0
    last: PoseResult | None = None
    _detector: object = field(default=None, repr=False)

    def __post_init__(self) -> None:
        # frames of footage: no turned second looks (a miss costs a frame; on the dim
        # webcam render a turned look fitted a whole hand onto the thumb, a start 420 mm
        # off, where the classic detector's was 14 mm off; docs/initialisation.md)
        self._detector = make_detector(self.detector, self.model, classic_fallback=True,
                                       max_hands=MAX_HANDS, look_turned=False,
                                       remember_side=True)
        self._options = FitOptions(fit_scale=False)

    @property
    def detector_class(self) -> str:
        """The class name of the detector in use (``auto`` resolved)."""
        return type(self._detector).__name__

    def __call__(self, images: Sequence[np.ndarray], hand_scale: float = 1.0
                 ) -> np.ndarray | None:
        """The state (mm, rad) of a hand ``hand_scale`` times the size of :attr:`model`
        fitted to the hand detected in ``images`` (rig order): a state of ``model`` at
        ``hand_scale`` 1, else of ``scaled_model(model, hand_scale)`` (a tracker that
        measured the hand's size); None when no camera finds a hand or the fit does not
        match it."""
        self.calls += 1
        options = replace(self._options, scale=float(hand_scale))
        try:
            result = estimate_pose(list(images), self.rig, self._detector, self.model,
                                   options, self.side)
        except DigitEyesError:  # detections no hand pose explains: no state, as no hand
            return None
        self.seconds += sum(result.seconds.values())
        self.last = result
        fit = result.fit
        if fit is not None and not self._accepted(fit.reprojection_px):
            fit = self._best_single_camera(result, options)
        if fit is None:
            return None
        self.found += 1
        return fit.scaled_state()

    def size_hand(self, state: np.ndarray) -> tuple[np.ndarray, float]:
        """The hand's size from the last detections (:attr:`last`, those that gave the
        start ``state``) when two or more cameras saw the hand: they are fitted again with
        the scale free, and the size is taken when

        * that fit's median reprojection error is at most :data:`SIZE_FIT_MAX_PX`;
        * the size lies more than :data:`MIN_SIZE_CHANGE` from 1, and within
          :data:`~digiteyes.detect.hand_size.HAND_SCALE_RANGE` (the webcam pair's dim grey
          hand, of which MediaPipe labelled a part in both views, measured 0.5);
        * the palm alone (:func:`~digiteyes.detect.hand_size.palm_scale`) measures the
          same size within :data:`MIN_SIZE_CHANGE`: the fingers' keypoints sit by the
          detector's convention, which in some views reads a hand of the model's size at
          0.9 (docs/initialisation.md).

        Rehg Sec. 2.2.3 names the hand's scale among the parameters to calibrate; a second
        camera observes it.

        Returns ``(state, scale)``: the state that poses the measured hand (palm in mm, a
        state of ``scaled_model(model, scale)``) and its size relative to :attr:`model`,
        which from then on is that model (later fits, the recoveries, are of it); or
        ``(state, 1.0)`` unchanged."""
        if self.last is None:
            return state, 1.0
        observations = [KeypointObservation.of(candidate, camera) for camera, candidate
                        in zip(self.rig, self.last.candidates, strict=True)
                        if candidate is not None]
        if len(observations) < 2:
            return state, 1.0
        started = time.perf_counter()
        try:
            fit = fit_keypoints(self.model, observations,
                               options=replace(self._options, fit_scale=True))
        except DigitEyesError:
            return state, 1.0
        finally:
            self.seconds += time.perf_counter() - started
        errors = fit.reprojection_px[np.isfinite(fit.reprojection_px)]
        low, high = HAND_SCALE_RANGE
        if (not errors.size or np.median(errors) > SIZE_FIT_MAX_PX
                or abs(fit.scale - 1.0) <= MIN_SIZE_CHANGE or not low <= fit.scale <= high):
            return state, 1.0
        palm = palm_scale(self.model, self.rig, [None if c is None else c.keypoints
                                                 for c in self.last.candidates])
        if palm is None or abs(palm - fit.scale) > MIN_SIZE_CHANGE:
            return state, 1.0
        self.model = scaled_model(self.model, fit.scale, name=self.model.name)
        return fit.scaled_state(), float(fit.scale)

    def _accepted(self, reprojection_px: np.ndarray) -> bool:
        errors = reprojection_px[np.isfinite(reprojection_px)]
        return bool(errors.size
                    and np.mean(errors <= self.max_error_px) >= MIN_DETECTED_FRACTION)

    def _best_single_camera(self, result: PoseResult, options: FitOptions) -> PoseFit | None:
        """When the cameras' detections disagree (a detector labels a hand seen from the
        palm in one view and from the back in another), the best fit to one camera alone
        that matches its detection; the depth then comes from the hand's size."""
        started = time.perf_counter()
        fits = []
        for camera, candidate in zip(self.rig, result.candidates, strict=True):
            if candidate is None or len(self.rig) == 1:
                continue
            observation = KeypointObservation.of(candidate, camera)
            try:
                fit = fit_keypoints(self.model, [observation], options=options)
            except DigitEyesError:
                continue
            if self._accepted(fit.reprojection_px):
                fits.append(fit)
        self.seconds += time.perf_counter() - started
        return min(fits, key=lambda f: float(np.median(f.reprojection_px)), default=None)


def start_automatically(initialiser: AutoInitialiser, frames: Iterator[list[np.ndarray]],
                        max_frames: int | None = None,
                        progress: Callable[[int], None] | None = None,
                        ) -> tuple[np.ndarray, int, Iterator]:
    """Run ``initialiser`` on the frames in turn until it finds the hand.

    ``max_frames`` bounds the search (None: until the input ends, e.g. a video whose hand
    enters late, or a live camera until the hand is raised); ``progress(k)`` is called
    after each frame ``k`` that showed no hand. Returns ``(state, skipped, frames)``: the
    state fitted to frame ``skipped`` (the frames before it had no hand and are not
    tracked) and the frames from that one on. Raises :class:`DatasetError` when none of
    them shows a hand.
    """
    searched = 0
    while max_frames is None or searched < max_frames:
        images = next(frames, None)
        if images is None:
            break
        state = initialiser(images)
        if state is not None:
            return state, searched, chain([images], frames)
        searched += 1
        if progress is not None:
            progress(searched - 1)
    raise DatasetError(f"--init auto: no hand found in {searched} frame(s) "
                       f"(detector {initialiser.detector!r}); give an initial state with "
                       "--init FILE")
