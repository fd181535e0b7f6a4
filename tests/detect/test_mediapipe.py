"""The MediaPipe detector: a clear error without the extra; candidates in the 21-keypoint
order on a real frame when both the extra and the real data are present."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest

from digiteyes.detect.mediapipe_detector import MediaPipeDetector, mediapipe_available
from digiteyes.errors import DigitEyesError

VIDEO = Path(__file__).resolve().parents[3] / "shared" / "data" / "real_video" / \
    "human_hand_video.mp4"


def test_missing_extra_names_the_install_command(monkeypatch):
    monkeypatch.setitem(sys.modules, "mediapipe", None)  # import fails as if absent
    assert not mediapipe_available()
    with pytest.raises(DigitEyesError, match=r'pip install "digiteyes\[mediapipe\]"'):
        MediaPipeDetector()


@pytest.mark.skipif(not mediapipe_available(), reason="optional extra digiteyes[mediapipe]")
def test_mediapipe_on_an_empty_image_finds_nothing():
    detector = MediaPipeDetector()
    assert detector.detect(np.full((240, 320), 128, dtype=np.uint8)) == []
    with pytest.raises(DigitEyesError, match="uint8"):
        detector.detect(np.zeros((240, 320, 3)))


@pytest.mark.skipif(not mediapipe_available(), reason="optional extra digiteyes[mediapipe]")
def test_mediapipe_is_handed_the_callers_pixels_read_only_not_a_copy():
    """MediaPipe copies a writable array and wraps a read-only one: the detector passes
    a read-only view of the caller's image, whose own array stays writable."""
    detector = MediaPipeDetector(max_hands=1, static_image_mode=False)
    passed, process = [], detector._hands.process
    detector._hands.process = lambda image: passed.append(image) or process(image)
    image = np.zeros((240, 320, 3), np.uint8)
    image[..., 0] = 200  # colour: one look, no grey tint
    assert detector.detect(image) == []
    assert len(passed) == 1 and np.shares_memory(passed[0], image)
    assert not passed[0].flags.writeable and image.flags.writeable


@pytest.mark.skipif(not (mediapipe_available() and VIDEO.is_file()),
                    reason="needs the mediapipe extra and ../shared/data")
def test_mediapipe_finds_the_right_hand_of_the_real_video():
    from digiteyes.detect.classic import ClassicDetector
    from digiteyes.io.video import VideoReader

    with VideoReader(VIDEO) as reader:
        frame = reader.read()
    found = MediaPipeDetector(max_hands=1).detect(frame)
    assert len(found) == 1 and found[0].handedness == "right"
    cand = found[0]
    assert cand.keypoints.shape == (21, 2) and cand.keypoints_3d.shape == (21, 3)
    classic = ClassicDetector().detect(frame)[0]
    tips = [4, 8, 12, 16, 20]  # both detectors put each named fingertip in the same place
    gap = np.linalg.norm(classic.keypoints[tips] - cand.keypoints[tips], axis=1)
    assert gap.max() < 25.0, gap


@pytest.mark.skipif(not mediapipe_available(), reason="optional extra digiteyes[mediapipe]")
@pytest.mark.parametrize("name", ["mediapipe", "mediapipe-lite"])
def test_both_networks_find_the_fingertips_of_the_flesh_hand(name):
    """The desk camera's colour render of the independent flesh hand: both landmark
    networks (``--detector mediapipe`` and ``mediapipe-lite``) put the five fingertips
    within 10 px of the true projections."""
    from digiteyes.benchmarks.tracker import render_sequence
    from digiteyes.detect.hand21 import DIGITS
    from digiteyes.detect.pose import make_detector
    from digiteyes.synth.setups import setup_scenario

    sequence = render_sequence(setup_scenario("desk", 2, n_frames=1), appearance="flesh",
                               color=True)
    names = list(sequence.truth.keypoint_names)
    truth = sequence.truth.keypoints_2d[0, 0, [names.index(f"{d}.tip") for d in DIGITS]]
    found = make_detector(name).detect(sequence.images[0][0], sequence.rig[0])
    assert len(found) == 1 and found[0].handedness == "right"
    error = np.linalg.norm(found[0].keypoints[[4, 8, 12, 16, 20]] - truth, axis=1)
    assert error.max() < 10.0, error


def _resident_mb() -> float:
    """The process's resident memory, MB (Linux)."""
    status = Path("/proc/self/status").read_text()
    return int(status.split("VmRSS:")[1].split()[0]) / 1024


@pytest.mark.skipif(not (mediapipe_available() and Path("/proc/self/status").is_file()),
                    reason="optional extra digiteyes[mediapipe]; Linux memory figures")
def test_a_dropped_detector_releases_its_graph():
    """MediaPipe keeps a graph its object no longer reaches (about 75 MB each, to the end of
    the process: a benchmark creating detectors for many runs was killed for memory).
    Dropped without close(), a detector stops its graph; close() is idempotent."""
    import gc

    detector = MediaPipeDetector(static_image_mode=False)
    hands = detector._hands
    del detector
    gc.collect()
    assert hands._graph is None  # SolutionBase.close() ran
    closed = MediaPipeDetector()
    closed.close()
    closed.close()
    assert closed._hands._graph is None
    frame = np.zeros((240, 320, 3), np.uint8)
    MediaPipeDetector(static_image_mode=False).detect(frame)  # the first one's allocations
    gc.collect()
    before = _resident_mb()
    for _ in range(6):
        MediaPipeDetector(static_image_mode=False).detect(frame)
        gc.collect()
    assert _resident_mb() - before < 150  # unreleased: about 450 MB


def test_unknown_detector_names_the_choices():
    from digiteyes.detect.pose import DETECTORS, make_detector

    with pytest.raises(DigitEyesError, match="mediapipe-lite"):
        make_detector("mediapipe-heavy")
    assert "mediapipe-lite" in DETECTORS


def test_video_mode_reaches_mediapipe(monkeypatch):
    """``make_detector(..., video=True)`` asks MediaPipe for its video mode (landmarks
    followed from frame to frame), the default for its image mode, each network at its
    complexity; the classic detector is the same either way."""
    import digiteyes.detect.mediapipe_detector as mp_module
    from digiteyes.detect.classic import ClassicDetector
    from digiteyes.detect.pose import make_detector

    made = []
    monkeypatch.setattr(mp_module, "MediaPipeDetector", lambda **kw: made.append(kw) or kw)
    for name in ("mediapipe", "mediapipe-lite"):
        for video in (False, True):
            make_detector(name, video=video)
    assert [(k["static_image_mode"], k["model_complexity"]) for k in made] == [
        (True, 1), (False, 1), (True, 0), (False, 0)]
    assert all(k["max_hands"] == 1 for k in made)
    assert isinstance(make_detector("classic", video=True), ClassicDetector)


@pytest.mark.skipif(not mediapipe_available(), reason="optional extra digiteyes[mediapipe]")
def test_native_start_up_notices_stay_off_standard_error():
    """A fresh process that builds both kinds of graph and detects shows nothing on its
    standard error but what Python writes (MediaPipe's native notices are written by the
    graph's threads as it starts, after its constructor has returned)."""
    import subprocess
    import time

    script = ("import sys, time, numpy as np\n"
              "from digiteyes.detect.mediapipe_detector import MediaPipeDetector\n"
              "for video in (False, True):\n"
              "    detector = MediaPipeDetector(static_image_mode=not video)\n"
              "    time.sleep(0.3)\n"
              "    detector.detect(np.zeros((120, 160, 3), np.uint8))\n"
              "print('ours', file=sys.stderr)\n")
    start = time.perf_counter()
    run = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True,
                         timeout=120)
    assert run.returncode == 0, run.stderr
    assert run.stderr.strip() == "ours", (run.stderr, time.perf_counter() - start)


def test_grey_images_are_recognised_and_tinted_keeping_their_grey_levels(tmp_path):
    """A 2-D image, RGB of three equal channels and a grey video as decoded (channels a
    level or two apart after chroma subsampling) are grey; a colour frame is not. The skin
    tint keeps each grey level (OpenCV's own RGB-to-grey conversion gives it back to
    within a level below the red channel's clipping) and has the skin's hue."""
    import cv2

    from digiteyes.detect.mediapipe_detector import is_grey, skin_tinted
    from digiteyes.io.video import VideoReader

    rng = np.random.default_rng(0)
    grey = cv2.GaussianBlur(rng.integers(0, 256, (96, 128), dtype=np.uint8), (9, 9), 3)
    assert is_grey(grey) and is_grey(np.repeat(grey[..., None], 3, axis=2))
    path = tmp_path / "grey.mp4"
    writer = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*"mp4v"), 10.0, (128, 96))
    writer.write(cv2.cvtColor(grey, cv2.COLOR_GRAY2BGR))
    writer.release()
    with VideoReader(path) as reader:
        decoded = reader.read()
    assert not np.array_equal(decoded[..., 0], decoded[..., 1]) and is_grey(decoded)
    colour = np.repeat(grey[..., None], 3, axis=2)
    colour[..., 0] = np.clip(colour[..., 0].astype(int) + 20, 0, 255)  # a reddish cast
    assert not is_grey(colour)
    tinted = skin_tinted(grey)
    assert tinted.shape == (96, 128, 3) and tinted.dtype == np.uint8
    back = cv2.cvtColor(tinted, cv2.COLOR_RGB2GRAY).astype(int)
    unclipped = grey < 193
    assert np.abs(back - grey)[unclipped].max() <= 1
    assert (tinted[..., 0] >= tinted[..., 1]).all() and (tinted[..., 1] >= tinted[..., 2]).all()


@pytest.mark.skipif(not mediapipe_available(), reason="optional extra digiteyes[mediapipe]")
def test_the_tint_lets_mediapipe_find_a_dim_grey_hand():
    """The webcam's grey render of the flesh hand (dim, before a dark backdrop): MediaPipe
    finds the hand, within 0.5 palm lengths of the truth, in more frames once the grey
    levels carry a skin hue (docs/real-data.md has the counts on real images)."""
    from digiteyes.detect.check import palm_gap
    from digiteyes.detect.hand21 import model_anchors
    from digiteyes.kinematics import forward_kinematics
    from digiteyes.synth import RenderOptions, render_views
    from digiteyes.synth.setups import setup_scenario

    scenario = setup_scenario("webcam", 1, n_frames=120)
    camera = scenario.rig.cameras[0]
    options = RenderOptions(appearance="flesh", noise_sigma=2.0)
    detectors = {grey_as_skin: MediaPipeDetector(max_hands=1, grey_as_skin=grey_as_skin)
                 for grey_as_skin in (False, True)}
    found = dict.fromkeys(detectors, 0)
    for frame in range(0, 120, 15):
        state = scenario.states[frame]
        image = render_views(scenario.model, state, scenario.rig, options, rng=frame)[0].image
        assert image.ndim == 2
        truth = camera.project(forward_kinematics(scenario.model, state).points(
            *model_anchors(scenario.model)))
        for grey_as_skin, detector in detectors.items():
            hit = detector.detect(image)
            found[grey_as_skin] += bool(hit) and palm_gap(truth, hit[0].keypoints) < 0.5
    assert found[True] >= 3 and found[True] > found[False], found


FREIHAND = VIDEO.parents[1] / "annotated_images" / "tests" / "data" / "freihand"


@pytest.mark.skipif(not (mediapipe_available() and (FREIHAND / "00065475.jpg").is_file()),
                    reason="needs the mediapipe extra and ../shared/data")
def test_a_hand_missed_upright_is_found_in_the_turned_image():
    """FreiHAND's image 00065475 (a fist held sideways): MediaPipe finds no hand in it
    upright, and finds it a quarter turn clockwise; turned back, its keypoints lie on the
    annotated ones (mean within 25 px in the 224 px image, the six hands found upright
    in 10-12 px); video mode does not turn."""
    import json

    import cv2

    meta = json.loads((FREIHAND / "test_freihand.json").read_text())
    image_id = next(im["id"] for im in meta["images"] if im["file_name"] == "00065475.jpg")
    truth = np.array(next(a["keypoints"] for a in meta["annotations"]
                          if a["image_id"] == image_id), dtype=float).reshape(21, 3)[:, :2]
    rgb = cv2.cvtColor(cv2.imread(str(FREIHAND / "00065475.jpg")), cv2.COLOR_BGR2RGB)

    assert MediaPipeDetector(max_hands=2, look_turned=False).detect(rgb) == []
    assert MediaPipeDetector(max_hands=2, static_image_mode=False).detect(rgb) == []
    found = MediaPipeDetector(max_hands=2).detect(rgb)
    assert len(found) == 1
    error = np.linalg.norm(found[0].keypoints - truth, axis=1)
    assert error.mean() < 25.0, error


@pytest.mark.skipif(not (mediapipe_available() and (FREIHAND / "00065475.jpg").is_file()),
                    reason="needs the mediapipe extra and ../shared/data")
def test_single_images_are_turned_and_frames_of_footage_are_not(hand):
    """``pose`` finds FreiHAND's sideways fist (turned); the automatic start of a track,
    which looks at frames of footage, does not turn them and finds no hand there."""
    import cv2

    from digiteyes.camera import Rig
    from digiteyes.camera.default import default_camera
    from digiteyes.detect.initialiser import AutoInitialiser
    from digiteyes.detect.pose import estimate_pose, make_detector

    rgb = cv2.cvtColor(cv2.imread(str(FREIHAND / "00065475.jpg")), cv2.COLOR_BGR2RGB)
    rig = Rig((default_camera(224, 224),))
    assert make_detector("mediapipe").look_turned
    assert not make_detector("mediapipe", look_turned=False).look_turned
    assert not make_detector("mediapipe", video=True).look_turned
    pose = estimate_pose([rgb], rig, make_detector("mediapipe", hand, max_hands=2), hand)
    assert pose.candidates[0] is not None
    start = AutoInitialiser(hand, rig, "mediapipe")
    assert start([rgb]) is None and start.found == 0
