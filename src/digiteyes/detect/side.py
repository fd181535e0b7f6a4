"""Which of the hands a detector found is the tracked one: its side, then its nearness.

The hand model is a right hand, and a left hand is tracked as the right hand of the mirror
image (:mod:`digiteyes.camera.mirror`), so in the images a tracker or an initialiser sees,
the tracked hand is a right one (:data:`TRACKED_SIDE`). A detector that tells the side
(MediaPipe's handedness) then tells the tracked hand from another one in view: the
user's other hand, a second person's. Without it a run could fit the wrong hand: with
the real video's hand and a second, left hand pasted beside it, ``--hand left`` tracked
the right one in every frame, with a warning.

A candidate is taken for the other hand only when the detector names the other side
with a score of at least :data:`OTHER_SIDE_CONFIDENCE`: MediaPipe (in video mode) named
the side of the real video's hand right in all 621 frames, and of the flesh renders' hand
in 598 of 600 frames (desk pair, desk, egocentric and mouse views, 120 frames each); the
two misnamed frames scored 0.52 and 0.54. But not always with a low score: it took the
back-lit palm of the rendered webcam view for the back of a left hand with 0.99. So while
tracking, where the tracked hand is known, a hand named the other side that lies where
the tracked one is (within :data:`SAME_HAND_PALMS` palm lengths) is the tracked hand
misnamed. A detector that cannot tell the side (the classic one) never names the other
hand.

:class:`SideFollower` keeps a video-mode detector on the tracked hand. MediaPipe in video
mode follows the hands it found: looking for one hand it runs its palm detector only when
it loses that hand (10 ms a 1280x720 frame on one core), looking for two it runs it in
every frame while it follows fewer (21 ms). So the follower looks for one hand, and only
when that one is the other hand does a second detector, looking for two, take over, until
the other hand has been out of its view for :data:`SWITCH_BACK_FRAMES` frames.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

import numpy as np

from digiteyes.camera import Camera
from digiteyes.detect.candidate import HandCandidate, HandDetector

TRACKED_SIDE = "right"
"""The side of the tracked hand in the images a tracker sees (the model's side)."""
OTHER_SIDE_CONFIDENCE = 0.8
"""Score at which a detector's naming of the other side is believed (module docstring)."""
SAME_HAND_PALMS = 1.0
"""A hand named the other side whose keypoints lie within this many palm lengths (wrist
to middle MCP) of the tracked hand's, on average, is the tracked hand (module docstring)."""
SWITCH_BACK_FRAMES = 30
"""Frames without the other hand after which :class:`SideFollower` looks for one hand
again."""


def is_other_hand(candidate: HandCandidate, side: str = TRACKED_SIDE,
                  near: np.ndarray | None = None) -> bool:
    """True when the detector names the side of ``candidate`` the other one than ``side``,
    with a score of at least :data:`OTHER_SIDE_CONFIDENCE`, and (given ``near``, the
    tracked hand's 21 keypoints (21, 2) px) it lies more than :data:`SAME_HAND_PALMS` palm
    lengths from them."""
    if not (candidate.handedness is not None and candidate.handedness != side
            and candidate.confidence >= OTHER_SIDE_CONFIDENCE):
        return False
    if near is None:
        return True
    palm = max(float(np.linalg.norm(near[0] - near[9])), 1.0)
    return _mean_distance(candidate, near) > SAME_HAND_PALMS * palm


def pick_candidate(found: Sequence[HandCandidate], side: str | None = TRACKED_SIDE,
                   near: np.ndarray | None = None) -> HandCandidate | None:
    """The tracked hand among a detector's candidates (best first): of those not named the
    other side, the one whose keypoints lie nearest ``near`` (21, 2) px, else the first.
    ``side`` None takes any side. None when none is left."""
    pool = [c for c in found if side is None or not is_other_hand(c, side, near)]
    if not pool:
        return None
    if near is None:
        return pool[0]
    return min(pool, key=lambda c: _mean_distance(c, near))


def _mean_distance(candidate: HandCandidate, keypoints: np.ndarray) -> float:
    """Mean distance (px) of the candidate's 21 keypoints from ``keypoints`` (21, 2)."""
    return float(np.mean(np.linalg.norm(candidate.keypoints - keypoints, axis=1)))


class SideFollower:
    """A video-mode detector that stays on the hand of ``side`` (module docstring).

    Parameters
    ----------
    make : ``make(max_hands)`` creates a video-mode detector looking for that many hands
        (e.g. :func:`~digiteyes.detect.pose.make_detector` with ``video=True``).
    side : the tracked hand's side in the images.
    """

    def __init__(self, make: Callable[[int], HandDetector], side: str = TRACKED_SIDE) -> None:
        self._make, self.side = make, side
        self._one = make(1)
        self._two: HandDetector | None = None
        self.following_two = False
        """True while the detector looking for two hands is in use."""
        self._without_other = 0
        self.name = self._one.name
        self.locates_joints = getattr(self._one, "locates_joints", False)

    def detect(self, image: np.ndarray, camera: Camera | None = None,
               near: np.ndarray | None = None) -> list[HandCandidate]:
        """The hands in ``image``, best first (the tracked one is for the caller to pick,
        :func:`pick_candidate`); ``near``: the tracked hand's keypoints (21, 2) px, when
        known (:func:`is_other_hand`). While the other hand is known to be in view (the
        detector looking for two is in use) a candidate that is the other hand is left
        out, so a frame that shows only it shows no tracked hand."""
        if not self.following_two:
            found = self._one.detect(image, camera)
            if not found or not all(is_other_hand(c, self.side, near) for c in found):
                return found
            self.following_two, self._without_other = True, 0
            if self._two is None:
                self._two = self._make(2)
        found = self._two.detect(image, camera)
        ours = [c for c in found if not is_other_hand(c, self.side, near)]
        self._without_other = 0 if len(ours) < len(found) else self._without_other + 1
        if self._without_other >= SWITCH_BACK_FRAMES:
            self.following_two = False
        return ours

    def close(self) -> None:
        """Release the detectors (MediaPipe's graphs)."""
        for detector in (self._one, self._two):
            getattr(detector, "close", lambda: None)()


__all__ = ["OTHER_SIDE_CONFIDENCE", "SAME_HAND_PALMS", "SWITCH_BACK_FRAMES", "TRACKED_SIDE",
           "SideFollower",
           "is_other_hand", "pick_candidate"]
