"""The detector's check of a track: quiet when the track is on the detected hand, a loss
reason naming the digit when it is not, silent where no hand is seen; in the run loop a
reason marks the frame lost and hands it to the recovery."""

from __future__ import annotations

import numpy as np

from digiteyes.camera import Rig
from digiteyes.detect.candidate import HandCandidate
from digiteyes.detect.check import DetectionCheck
from digiteyes.detect.hand21 import model_anchors
from digiteyes.kinematics import forward_kinematics
from digiteyes.pipeline import run_tracker
from digiteyes.trackers import TrackResult


class Seen:
    """A detector that reports the keypoints of a fixed state (none when ``state`` is
    None)."""

    def __init__(self, model, state):
        self.model, self.state = model, state

    def detect(self, image, camera=None, near=None):  # as a SideFollower
        if self.state is None:
            return []
        rows, points = model_anchors(self.model)
        uv = camera.project(forward_kinematics(self.model, self.state).points(rows, points))
        return [HandCandidate(uv, np.ones(21), 0.9, (0, 0, 1, 1), "right", "seen")]


def a_check(hand, camera, seen_state, every=1):
    check = DetectionCheck(hand, Rig((camera,)), "classic", every=every)
    check._detectors = [Seen(hand, seen_state)]
    return check


def bent_index(hand, q):
    """``q`` with the index finger's flexion joints moved to their far limits."""
    bent = q.copy()
    for joint in ("index.mcp", "index.pip", "index.dip"):
        i = hand.state_names.index(joint)
        middle = 0.5 * (hand.lower[i] + hand.upper[i])
        bent[i] = hand.upper[i] if q[i] < middle else hand.lower[i]
    return bent


def test_a_track_on_the_detected_hand_passes_and_one_finger_off_is_named(hand, camera,
                                                                        posed):
    q = posed(hand, 0)
    image = [np.zeros((480, 640), np.uint8)]
    assert a_check(hand, camera, q)(0, image, q) is None
    bent = bent_index(hand, q)
    check = a_check(hand, camera, q)
    reason = check(0, image, bent)
    assert reason is not None and "index" in reason and check.disagreements == 1
    assert a_check(hand, camera, None)(0, image, bent) is None  # no hand seen: no verdict
    assert a_check(hand, camera, q, every=3)(1, image, bent) is None  # not a checked frame


class Still:
    """A tracker that stays where it was started and never calls itself lost."""

    stages = ()

    def __init__(self, model, rig):
        self.model, self.rig = model, rig

    def reset(self, state):
        self.state = np.asarray(state, dtype=float)

    def step(self, frames):
        return TrackResult(self.state.copy(), 0.0, 0.0, False, "", 1)


def test_in_the_run_loop_a_reason_marks_the_frame_lost_and_the_recovery_runs(hand, camera,
                                                                           posed, tmp_path):
    rig = Rig((camera,))
    truth = posed(hand, 0)
    start = bent_index(hand, truth)
    frames = [[np.zeros((480, 640), np.uint8)]] * 4
    check = a_check(hand, camera, truth)
    asked = []

    def recover(images, hand_scale):
        asked.append(len(asked))
        return truth

    run = run_tracker(Still(hand, rig), hand, rig, frames, start, tmp_path / "r",
                      overlay=False, progress=False, views_every=0, warm=False,
                      recover=recover, check=check)
    assert run.n_lost == 1 and run.reinitialised_frames == [0] and asked == [0]
    assert check.checks == 4 and check.disagreements == 1  # on the hand after the re-fit
