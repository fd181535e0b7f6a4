"""A track checked against a learned detector's keypoints (ours): the loss flag on footage.

The trackers' own loss rules judge a track by what the tracker measures: residuals, edge
hits, and the silhouette where the backdrop is plain. On real footage before an ordinary
backdrop none of that sees a track that has left the hand: on the real video the feature
tracker was more than half a palm length off MediaPipe's keypoints in 93 % of the frames
while it flagged 7 (docs/keypoint-tracker.md). :class:`DetectionCheck` runs the detector
every ``every`` frames and compares: for each digit, the mean distance of its four
keypoints (projected from the state) to the detected ones, in palm lengths (the detected
wrist to middle MCP); a digit more than ``max_gap`` off in any camera that sees the hand
makes the frame lost. The run loop then re-detects and re-fits as after any loss
(:func:`digiteyes.pipeline.run_tracker`). Frames where the detector sees no hand are not
judged (the tracker's own rules still are).
"""

from __future__ import annotations

import time
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from digiteyes.camera import Rig
from digiteyes.detect.hand21 import DIGIT_KEYPOINTS, PALM, model_anchors
from digiteyes.detect.pose import make_detector
from digiteyes.detect.side import TRACKED_SIDE, SideFollower, pick_candidate
from digiteyes.kinematics import KinematicModel, forward_kinematics


def keypoint_gaps(tracked: np.ndarray, detected: np.ndarray) -> np.ndarray | None:
    """Each keypoint's distance (21,) from the detected one in palm lengths (the
    detection's wrist to middle MCP): tracked and detected (21, 2) px of one image. None
    for a detection without a palm length."""
    palm = float(np.linalg.norm(detected[0] - detected[9]))
    if not palm > 0:
        return None
    return np.linalg.norm(tracked - detected, axis=1) / palm


def worst_digit_gap(tracked: np.ndarray, detected: np.ndarray) -> tuple[float, str] | None:
    """The digit whose four keypoints lie farthest from the detected ones on average, and
    that distance in palm lengths (:func:`keypoint_gaps`). None for a detection without a
    palm length."""
    gap = keypoint_gaps(tracked, detected)
    if gap is None:
        return None
    return max((float(gap[keys].mean()), digit) for digit, keys in DIGIT_KEYPOINTS.items())


def palm_gap(tracked: np.ndarray, detected: np.ndarray) -> float | None:
    """The mean distance of the palm's keypoints (:data:`~digiteyes.detect.hand21.PALM`) from the
    detected ones in palm lengths (:func:`keypoint_gaps`). None for a detection without a
    palm length."""
    gap = keypoint_gaps(tracked, detected)
    return None if gap is None else float(gap[list(PALM)].mean())


@dataclass
class DetectionCheck:
    """The check of the module docstring; callable as ``check(index, images, state)``.

    Attributes
    ----------
    model, rig : the tracker's model and cameras.
    detector : a learned detector's name (``"auto"``, ``"mediapipe"``,
        ``"mediapipe-lite"``), run in video mode, one per camera.
    every : frames between checks (the first frame is checked).
    max_gap : a digit farther than this (palm lengths) from the detection is off.
    checks, disagreements, seconds : how often it ran, found the track off, and its time.
    """

    model: KinematicModel
    rig: Rig
    detector: str = "auto"
    every: int = 3
    max_gap: float = 0.5
    checks: int = 0
    disagreements: int = 0
    seconds: float = 0.0
    _detectors: list = field(default_factory=list, repr=False)

    def __post_init__(self) -> None:
        self._anchors = model_anchors(self.model)
        self._detectors = [SideFollower(lambda hands: make_detector(
            self.detector, self.model, video=True, max_hands=hands)) for _ in self.rig]

    def __call__(self, index: int, images: Sequence[np.ndarray], state: np.ndarray
                 ) -> str | None:
        """Why the track at ``state`` (n_q,) is off the detected hand in frame ``index``
        (a loss reason), or None when it is on it, the detector sees no hand, or the frame
        is not one to check."""
        if index % self.every:
            return None
        self.checks += 1
        worst = self.worst_digit(images, state)
        if worst is None or worst[0] <= self.max_gap:
            return None
        self.disagreements += 1
        return (f"the detector sees the {worst[1]} {worst[0]:.2f} palm lengths from the "
                "track")

    def worst_digit(self, images: Sequence[np.ndarray], state: np.ndarray
                    ) -> tuple[float, str] | None:
        """The largest gap (palm lengths) of a digit between ``state`` (n_q,) and the
        detections in ``images``, over the cameras that see a hand, and that digit; None
        when no camera sees one."""
        started = time.perf_counter()
        rows, points = self._anchors
        world = forward_kinematics(self.model, np.asarray(state, dtype=float)).points(rows,
                                                                                     points)
        worst: tuple[float, str] | None = None
        for detector, image, camera in zip(self._detectors, images, self.rig, strict=True):
            projected = camera.project(world)
            found = pick_candidate(detector.detect(image, camera, projected), TRACKED_SIDE,
                                   projected)
            here = worst_digit_gap(projected, found.keypoints) if found is not None else None
            if here is not None:
                worst = here if worst is None else max(worst, here)
        self.seconds += time.perf_counter() - started
        return worst

    def to_json(self) -> dict:
        """What ``summary.json`` records of the check."""
        return {"every": self.every, "max_gap_palm_lengths": self.max_gap,
                "checks": self.checks, "disagreements": self.disagreements,
                "seconds": self.seconds}
