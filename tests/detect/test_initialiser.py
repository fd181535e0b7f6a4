"""The automatic start and recovery: a state from detections, None (not a crash) when the
detections cannot be fitted."""

from __future__ import annotations

import sys

import numpy as np
import pytest

from digiteyes.benchmarks.tracker import render_sequence
from digiteyes.camera import Camera, Rig
from digiteyes.detect import pose
from digiteyes.detect.candidate import HandCandidate
from digiteyes.detect.classic import ClassicDetector
from digiteyes.detect.fallback import FallbackDetector, keypoint_span
from digiteyes.detect.hand21 import model_anchors
from digiteyes.detect.hand_size import model_hand_length
from digiteyes.detect.initialiser import AutoInitialiser
from digiteyes.detect.mediapipe_detector import MediaPipeDetector, mediapipe_available
from digiteyes.kinematics import forward_kinematics
from digiteyes.kinematics.keypoints import keypoints
from digiteyes.kinematics.scaling import scaled_model
from digiteyes.synth.options import RenderOptions
from digiteyes.synth.scenarios import build_scenario
from digiteyes.synth.views import render_views


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


class Stub:
    """A detector returning fixed candidates of the given confidences."""

    locates_joints = True

    def __init__(self, name: str, confidences: list[float]) -> None:
        self.name, self.confidences, self.calls = name, confidences, 0
        self.points = np.zeros((2, 2))

    def detect(self, image, camera=None):
        self.calls += 1
        keypoints = np.resize(self.points, (21, 2))  # the given points, repeated
        return [HandCandidate(keypoints, np.ones(21), c, (0.0, 0.0, 1.0, 1.0), None,
                              self.name) for c in self.confidences]


def test_the_fallback_detector_asks_the_second_only_when_the_first_finds_nothing():
    image = np.zeros((4, 4), np.uint8)
    first, second = Stub("first", [0.9]), Stub("second", [0.8, 0.6])
    both = FallbackDetector(first, second)
    assert [c.detector for c in both.detect(image)] == ["first"] and second.calls == 0
    first.confidences = []
    found = both.detect(image)
    assert [(c.detector, c.confidence) for c in found] == [("second", 0.8)]  # 0.6 < 0.7
    assert second.calls == 1 and both.name == "first, else second"


def test_an_unsure_first_hand_gives_way_to_a_confident_second_that_spans_more():
    """A first-detector hand below 0.8 that spans a third of the second detector's
    (MediaPipe's part of a dim hand against its silhouette) comes after the second's;
    an unsure one of about the same span, or of a seventeenth (the second's silhouette is
    a body), or a sure one, stays first."""
    image = np.zeros((4, 4), np.uint8)
    square = np.array([[0.0, 0.0], [100.0, 100.0]])
    first, second = Stub("first", [0.6]), Stub("second", [0.75])
    first.points, second.points = square, 3.0 * square
    both = FallbackDetector(first, second)
    assert [c.detector for c in both.detect(image)] == ["second", "first"]
    second.points = 1.2 * square
    assert [c.detector for c in both.detect(image)] == ["first"]
    second.points = 17.0 * square  # a body's silhouette, not this hand
    assert [c.detector for c in both.detect(image)] == ["first"]
    second.points, second.confidences = 3.0 * square, [0.65]  # not confident: not taken
    assert [c.detector for c in both.detect(image)] == ["first"]
    first.confidences, calls = [0.85], second.calls
    assert [c.detector for c in both.detect(image)] == ["first"] and second.calls == calls
    assert keypoint_span(Stub("s", [1.0]).detect(image)[0]) == 0.0


def test_auto_falls_back_to_the_classic_detector_only_beside_mediapipe(hand, camera,
                                                                       monkeypatch):
    init = AutoInitialiser(hand, Rig((camera,)), "classic")
    assert isinstance(init._detector, ClassicDetector)
    if mediapipe_available():
        assert isinstance(pose.make_detector("auto", hand, classic_fallback=True),
                          FallbackDetector)
        assert not isinstance(pose.make_detector("auto", hand), FallbackDetector)
    monkeypatch.setitem(sys.modules, "mediapipe", None)  # the extra absent: classic alone
    assert isinstance(AutoInitialiser(hand, Rig((camera,)), "auto")._detector, ClassicDetector)
    assert isinstance(pose.make_detector("auto", hand, classic_fallback=True), ClassicDetector)


@pytest.mark.skipif(not mediapipe_available(), reason="optional extra digiteyes[mediapipe]")
def test_auto_starts_where_mediapipe_sees_no_hand():
    """The webcam render of the flesh hand (palm on, back-lit): MediaPipe finds no hand in
    it, the classic detector does, and the automatic start is within 20 mm."""
    scenario = build_scenario("webcam-1cam", seed=0, n_frames=1)
    options = RenderOptions(appearance="flesh", color=True, background="black",
                            background_level=0.08)
    image = render_views(scenario.model, scenario.states[0], list(scenario.rig.cameras),
                         options, rng=0)[0].image
    assert MediaPipeDetector().detect(image) == []
    init = AutoInitialiser(scenario.model, scenario.rig, "auto")
    assert isinstance(init._detector, FallbackDetector)
    state = init([image])
    assert state is not None and init.last.candidates[0].detector == "classic"
    _, start = keypoints(scenario.model, forward_kinematics(scenario.model, state[None]))
    _, true = keypoints(scenario.model, forward_kinematics(scenario.model,
                                                           scenario.states[:1]))
    assert np.linalg.norm(start - true, axis=2).mean() < 20.0


@pytest.mark.skipif(not mediapipe_available(), reason="optional extra digiteyes[mediapipe]")
def test_a_hand_mediapipe_sees_only_in_part_does_not_start_the_run_300_mm_away():
    """The webcam render of seed 3 (`bench auto-start`'s frames): MediaPipe labels part of
    the dim hand (confidence about 0.5); the fit of those keypoints put the start 400 mm
    off. The classic detector's silhouette shows the whole hand, and the start is within
    20 mm."""
    scenario = build_scenario("webcam-1cam", seed=3, n_frames=1)
    sequence = render_sequence(scenario, seed=3, appearance="flesh", color=True)
    found = MediaPipeDetector().detect(sequence.images[0][0])
    assert found and found[0].confidence < 0.8
    init = AutoInitialiser(scenario.model, sequence.rig, "auto")
    state = init(sequence.images[0])
    assert state is not None and init.last.candidates[0].detector == "classic"
    _, start = keypoints(scenario.model, forward_kinematics(scenario.model, state[None]))
    _, true = keypoints(scenario.model, forward_kinematics(scenario.model,
                                                           scenario.states[:1]))
    assert np.linalg.norm(start - true, axis=2).mean() < 20.0


def test_detections_no_pose_explains_are_reported_not_raised(hand, camera):
    """``pose`` on a batch goes on past an image whose detection the model cannot fit:
    the result has no fit and says why, and its JSON record carries the reason."""
    from digiteyes.detect.pose import estimate_pose, pose_to_json

    result = estimate_pose([np.zeros((480, 640), np.uint8)], Rig((camera,)),
                           FixedDetector(np.full((21, 2), 320.0)), hand)
    assert result.fit is None and result.candidates[0] is not None
    assert "palm pose" in result.fit_failure
    record = pose_to_json(result, Rig((camera,)), ["x.png"])
    assert record["hand"] is None and record["fit_failure"] == result.fit_failure


class ProjectingDetector:
    """A detector that reports given 3D keypoints (world, mm) as each camera sees them,
    with Gaussian pixel noise and, for the camera named ``shifted``, every keypoint moved
    by ``shift_px``."""

    name = "projecting"
    locates_joints = True

    def __init__(self, points: np.ndarray, noise_px: float = 1.0, shifted: str | None = None,
                 shift_px: float = 0.0) -> None:
        self.points, self.noise_px = points, noise_px
        self.shifted, self.shift_px = shifted, shift_px
        self.rng = np.random.default_rng(0)

    def detect(self, image, camera=None):
        pixels = camera.project(self.points) + self.rng.normal(0.0, self.noise_px, (21, 2))
        if camera.name == self.shifted:
            pixels = pixels + self.shift_px
        return [HandCandidate(pixels, np.ones(21), 0.9, (0.0, 0.0, 640.0, 480.0), "right",
                              self.name)]


def test_two_cameras_measure_the_hands_size_at_the_start(hand, camera, posed):
    """A hand 0.9 or 1.1 times the model's size seen by two cameras: the start is fitted at
    the model's size, then ``size_hand`` measures the size within 0.02, moves the
    initialiser to a model of that size, and returns the state that poses the hand where
    it is; a hand 1.02 times the size keeps the model's; detections the sized fit does not
    match (one view's keypoints 40 px off), a size outside ``HAND_SCALE_RANGE`` (0.5: part
    of a hand labelled as a whole one), or one camera, keep the model's too."""
    side = Camera.look_at("side", eye=(300, 0, 350), target=(0, 0, 0), up=(0, -1, 0))
    rig = Rig((camera, side))
    q = posed(hand, 3)
    images = [np.zeros((480, 640), np.uint8)] * 2
    for size, shift_px, cameras, expected in ((0.9, 0.0, rig, 0.9), (1.1, 0.0, rig, 1.1),
                                              (1.02, 0.0, rig, 1.0), (0.9, 40.0, rig, 1.0),
                                              (0.5, 0.0, rig, 1.0),
                                              (0.9, 0.0, Rig((camera,)), 1.0)):
        true_hand = scaled_model(hand, size)
        points = forward_kinematics(true_hand, q).points(*model_anchors(true_hand))
        init = AutoInitialiser(hand, cameras, "classic")
        init._detector = ProjectingDetector(points, shifted="side", shift_px=shift_px)
        start = init(images[:len(cameras)])
        assert start is not None
        state, scale = init.size_hand(start)
        assert scale == pytest.approx(expected, abs=0.02), (size, shift_px, len(cameras))
        if expected == 1.0:
            assert scale == 1.0 and state is start and init.model is hand
            continue
        assert init.model.name == hand.name
        assert model_hand_length(init.model) == pytest.approx(scale * model_hand_length(hand))
        anchors = model_anchors(init.model)
        posed_points = forward_kinematics(init.model, state).points(*anchors)
        assert np.linalg.norm(posed_points - points, axis=1).mean() < 4.0  # mm
        again = init(images)  # a recovery: a fit of the measured hand
        assert again is not None
        refit = forward_kinematics(init.model, again).points(*anchors)
        assert np.linalg.norm(refit - points, axis=1).mean() < 4.0


def test_the_size_is_taken_only_where_the_palm_measures_it_too(hand, camera, posed):
    """Detections of a hand 0.9 times the model's size whose fingers' keypoints sit short
    of the model's (each digit's last three keypoints drawn towards its base, as MediaPipe
    places a flesh hand's fingertips in some views): a fit of all 21 reads a smaller hand
    than the palm's triangulated keypoints do, and the model's size is kept; with the
    keypoints where the model has them both read 0.9."""
    from digiteyes.detect.hand_size import palm_scale

    side = Camera.look_at("side", eye=(300, 0, 350), target=(0, 0, 0), up=(0, -1, 0))
    rig = Rig((camera, side))
    true_hand = scaled_model(hand, 0.9)
    points = forward_kinematics(true_hand, posed(hand, 3)).points(*model_anchors(true_hand))
    short = points.copy()
    for base in (1, 5, 9, 13, 17):
        digit = slice(base + 1, base + 4)
        short[digit] = points[base] + 0.6 * (points[digit] - points[base])
    images = [np.zeros((480, 640), np.uint8)] * 2
    for detected, expected in ((points, 0.9), (short, 1.0)):
        init = AutoInitialiser(hand, rig, "classic")
        init._detector = ProjectingDetector(detected)
        start = init(images)
        assert start is not None
        palm = palm_scale(hand, rig, [c.keypoints for c in init.last.candidates])
        assert palm == pytest.approx(0.9, abs=0.02)
        assert init.size_hand(start)[1] == pytest.approx(expected, abs=0.02)


def test_a_recovery_fits_a_hand_of_the_size_the_tracker_measured(hand, camera, posed):
    """Asked for a hand 0.9 times the model's size (a tracker that measured it), the
    initialiser returns the state of the scaled model that poses the detected hand; at the
    model's size the same detections leave the fitted hand farther from them."""
    q = posed(hand, 5)
    small = scaled_model(hand, 0.9)
    anchors = model_anchors(small)
    points = forward_kinematics(small, q).points(*anchors)
    side = Camera.look_at("side", eye=(300, 0, 350), target=(0, 0, 0), up=(0, -1, 0))
    init = AutoInitialiser(hand, Rig((camera, side)), "classic")
    init._detector = ProjectingDetector(points, noise_px=0.5)
    images = [np.zeros((480, 640), np.uint8)] * 2
    state = init(images, hand_scale=0.9)
    sized = np.linalg.norm(forward_kinematics(small, state).points(*anchors) - points,
                           axis=1).mean()
    state = init(images)
    held = np.linalg.norm(forward_kinematics(hand, state).points(*model_anchors(hand))
                          - points, axis=1).mean()
    assert sized < 2.0 < held, (sized, held)
