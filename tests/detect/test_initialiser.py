"""The automatic start and recovery: a state from detections, None (not a crash) when the
detections cannot be fitted."""

from __future__ import annotations

import numpy as np

from digiteyes.camera import Rig
from digiteyes.detect.candidate import HandCandidate
from digiteyes.detect.hand21 import model_anchors
from digiteyes.detect.initialiser import AutoInitialiser
from digiteyes.kinematics import forward_kinematics


class FixedDetector:
    """A detector that reports the same keypoints for any image."""

    name = "fixed"
    locates_joints = True

    def __init__(self, keypoints: np.ndarray) -> None:
        self.keypoints = keypoints

    def detect(self, image, camera=None):
        return [HandCandidate(self.keypoints, np.ones(21), 0.9, (0.0, 0.0, 640.0, 480.0),
                              "right", self.name)]


def initialiser_with(hand, camera, keypoints) -> AutoInitialiser:
    init = AutoInitialiser(hand, Rig((camera,)), "classic")
    init._detector = FixedDetector(keypoints)
    return init


def test_a_hand_is_started_from_its_keypoints(hand, camera, posed):
    q = posed(hand, 0)
    rows, points = model_anchors(hand)
    pixels = camera.project(forward_kinematics(hand, q).points(rows, points))
    state = initialiser_with(hand, camera, pixels)([np.zeros((480, 640), np.uint8)])
    assert state is not None and state.shape == (hand.n_q,)
    fitted = camera.project(forward_kinematics(hand, state).points(rows, points))
    assert np.linalg.norm(fitted - pixels, axis=1).mean() < 2.0  # it explains the keypoints


def test_keypoints_no_pose_explains_give_no_state(hand, camera):
    """All 21 keypoints on one pixel: the palm fit has no pose in front of the camera; the
    recovery must then report no state, not stop the run."""
    init = initialiser_with(hand, camera, np.full((21, 2), 320.0))
    assert init([np.zeros((480, 640), np.uint8)]) is None
    assert init.calls == 1 and init.found == 0
