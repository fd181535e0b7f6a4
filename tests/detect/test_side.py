"""Which of several detected hands is the tracked one (:mod:`digiteyes.detect.side`): the
rules on made-up candidates, then MediaPipe on a render of the flesh hand beside its mirror
image (a right and a left hand in one picture), through ``pose`` and ``track``."""

from __future__ import annotations

import csv
import json

import cv2
import numpy as np
import pytest

from digiteyes.cli import main
from digiteyes.detect.candidate import HandCandidate, bbox_of
from digiteyes.detect.mediapipe_detector import mediapipe_available
from digiteyes.detect.side import (
    OTHER_SIDE_CONFIDENCE,
    SWITCH_BACK_FRAMES,
    SideFollower,
    is_other_hand,
    pick_candidate,
)

needs_mediapipe = pytest.mark.skipif(not mediapipe_available(),
                                     reason="optional extra digiteyes[mediapipe]")


def candidate(u: float, side: str | None = "right", score: float = 0.95) -> HandCandidate:
    """A hand whose 21 keypoints lie round column ``u``."""
    points = np.column_stack([np.linspace(u - 40, u + 40, 21), np.linspace(100, 300, 21)])
    return HandCandidate(points, np.ones(21), score, bbox_of(points), side, "test")


def test_only_a_confident_naming_of_the_other_side_counts():
    assert is_other_hand(candidate(0, "left", OTHER_SIDE_CONFIDENCE))
    assert not is_other_hand(candidate(0, "left", 0.52))  # a misnamed frame (module doc)
    assert not is_other_hand(candidate(0, "right"))
    assert not is_other_hand(candidate(0, None, 1.0))  # a detector that cannot tell
    assert is_other_hand(candidate(0, "right"), side="left")
    # named left where the tracked hand is (within a palm length): the tracked hand misnamed
    here = candidate(400).keypoints  # palm length (keypoint 0 to 9): about 100 px
    assert not is_other_hand(candidate(430, "left", 0.99), near=here)
    assert is_other_hand(candidate(700, "left", 0.99), near=here)


def test_pick_keeps_to_the_side_then_to_the_nearest():
    left, right, far_right = candidate(100, "left"), candidate(400), candidate(900)
    assert pick_candidate([left, right]) is right
    assert pick_candidate([left, right], side=None) is left  # any side: the first
    assert pick_candidate([left]) is None  # the other hand alone is not the tracked one
    assert pick_candidate([]) is None
    near = candidate(880).keypoints
    assert pick_candidate([right, far_right, left], near=near) is far_right
    assert pick_candidate([left, candidate(0, "left", 0.5)]).confidence == 0.5
    assert pick_candidate([left], near=candidate(110).keypoints) is left  # misnamed


class FakeDetector:
    """Returns the next frame's candidates from a script; counts its frames."""

    def __init__(self, script: list[list[HandCandidate]]) -> None:
        self.script, self.frames, self.closed = script, 0, False
        self.name, self.locates_joints = "fake", True

    def detect(self, image, camera=None) -> list[HandCandidate]:
        self.frames += 1
        return self.script[min(self.frames - 1, len(self.script) - 1)]

    def close(self) -> None:
        self.closed = True


def test_the_follower_looks_for_two_hands_only_while_the_other_one_is_followed():
    right, left = candidate(400), candidate(100, "left")
    n = SWITCH_BACK_FRAMES
    one = FakeDetector([[right], [left]] + [[right]] * (n + 5))
    two = FakeDetector([[right, left]] * 3 + [[right]] * (n + 5))
    made = []

    def make(hands: int) -> FakeDetector:
        made.append(hands)
        return {1: one, 2: two}[hands]

    follower = SideFollower(make)
    assert follower.detect(None) == [right] and made == [1]  # the tracked hand: one is enough
    assert follower.detect(None) == [right]  # the one-hand detector follows the left hand
    assert follower.following_two and made == [1, 2] and two.frames == 1
    assert follower.detect(None) == [right] and follower.detect(None) == [right]
    for _ in range(n - 1):  # the left hand has gone; the two-hand detector keeps watch
        follower.detect(None)
        assert follower.following_two
    follower.detect(None)
    assert not follower.following_two and two.frames == n + 3
    assert follower.detect(None) == [right] and one.frames == 3
    follower.close()
    assert one.closed and two.closed


def test_the_follower_shows_no_hand_when_only_the_other_one_is_in_view():
    left = candidate(100, "left")
    follower = SideFollower(lambda hands: FakeDetector([[left]]))
    assert follower.detect(None) == []


@pytest.fixture(scope="module")
def two_hands() -> np.ndarray:
    """Three frames (3, 480, 1280, 3) of the desk camera's colour render of the flesh hand
    (a right hand, in the right half) beside its mirror image drawn smaller (a left hand;
    smaller so that the picture is no mirror image of itself, and the detector ranks the
    same hand first whichever way it is turned)."""
    from digiteyes.benchmarks.tracker import render_sequence
    from digiteyes.synth.setups import setup_scenario

    sequence = render_sequence(setup_scenario("desk", 1, n_frames=3), appearance="flesh",
                               color=True)
    frames = []
    for images in sequence.images:
        image = images[0]
        height, width = image.shape[:2]
        small = cv2.resize(image[:, ::-1], (width * 3 // 4, height * 3 // 4))
        left = np.empty_like(image)
        left[:] = image[0, 0]  # the backdrop's colour
        top, side = (height - small.shape[0]) // 2, (width - small.shape[1]) // 2
        left[top:top + small.shape[0], side:side + small.shape[1]] = small
        frames.append(np.hstack([left, image]))
    return np.array(frames)


@needs_mediapipe
def test_each_side_finds_its_own_hand_in_a_picture_of_two(two_hands):
    from digiteyes.detect.pose import make_detector

    frames = two_hands
    width = frames.shape[2]
    detector = make_detector("mediapipe", max_hands=2)
    found = detector.detect(frames[0])
    assert sorted(c.handedness for c in found) == ["left", "right"]
    right = pick_candidate(found)
    assert right.keypoints[:, 0].min() > width / 2  # the right hand is the right half's
    # a left hand's run looks at the mirror image, where the left hand is a right one
    left = pick_candidate(detector.detect(np.ascontiguousarray(frames[0][:, ::-1])))
    assert left.keypoints[:, 0].min() > width / 2  # the real image's left half


@needs_mediapipe
@pytest.mark.parametrize("hand", ["right", "left"])
def test_pose_and_track_fit_the_hand_asked_for(two_hands, tmp_path, hand):
    frames = two_hands
    width = frames.shape[2]
    folder = tmp_path / "frames"
    folder.mkdir()
    for i, frame in enumerate(frames):
        cv2.imwrite(str(folder / f"frame_{i}.png"), cv2.cvtColor(frame, cv2.COLOR_RGB2BGR))

    def on_its_side(u: np.ndarray) -> bool:
        return bool((u > width / 2).all() if hand == "right" else (u < width / 2).all())

    assert main(["pose", str(folder / "frame_0.png"), "--hand", hand,
                 "-o", str(tmp_path / "pose")]) == 0
    record = json.loads((tmp_path / "pose" / "frame_0.json").read_text())
    pixels = np.array(list(record["detections"]["camera"]["keypoints_px"].values()))
    assert on_its_side(pixels[:, 0]), pixels[:, 0]

    assert main(["track", str(folder), "--hand", hand, "--fps", "10", "--no-overlay",
                 "--quiet", "-o", str(tmp_path / hand)]) == 0
    with open(tmp_path / hand / "keypoints.csv", newline="") as file:
        rows = list(csv.DictReader(file))
    assert len(rows) == len(frames)
    tips = [key for key in rows[0] if key.endswith(".tip.u_px")]
    assert len(tips) == 5
    assert on_its_side(np.array([[float(row[key]) for key in tips] for row in rows]))


@needs_mediapipe
def test_a_run_for_the_other_side_waits_and_says_why(two_hands, tmp_path, capsys):
    """Only the right hand in view and ``--hand left``: no start on it; the run says that
    the detector sees a right hand and, with nothing else found, fails with that hint."""
    frames = two_hands[:, :, two_hands.shape[2] // 2:]  # the right half: the right hand
    folder = tmp_path / "frames"
    folder.mkdir()
    for i, frame in enumerate(frames):
        cv2.imwrite(str(folder / f"frame_{i}.png"), cv2.cvtColor(frame, cv2.COLOR_RGB2BGR))
    code = main(["track", str(folder), "--hand", "left", "--fps", "10", "--no-overlay",
                 "--quiet", "-o", str(tmp_path / "out")])
    printed = capsys.readouterr()
    assert code != 0
    assert "no left hand in frame 0; the detector sees a right hand" in printed.out
    assert "--hand right, or auto" in printed.err
    assert main(["pose", str(folder / "frame_0.png"), "--hand", "left",
                 "-o", str(tmp_path / "pose")]) == 0
    assert "only a hand of the other side" in capsys.readouterr().out
