"""``digiteyes mouse`` on footage with nothing else (digiteyes.mouse_job): the hand is
found, tracked and mapped by its own start pose; measured against the truth of the
``hand-mouse`` scenario rendered with the independent flesh appearance."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from digiteyes.apps.palm_mouse import PalmMouse
from digiteyes.detect.mediapipe_detector import mediapipe_available
from digiteyes.errors import DatasetError
from digiteyes.mouse_job import footage_mouse_frames, open_footage_mouse
from digiteyes.synth import RenderOptions, render_views
from digiteyes.synth.scenarios import build_scenario

FLESH = RenderOptions(color=True, appearance="flesh", noise_sigma=2.0)
needs_mediapipe = pytest.mark.skipif(not mediapipe_available(),
                                     reason="optional extra digiteyes[mediapipe]")


def rendered(scenario, frames: range) -> list[list[np.ndarray]]:
    return [[render_views(scenario.model, scenario.states[t], scenario.rig, FLESH,
                          np.random.default_rng([0, t]))[0].image] for t in frames]


@pytest.fixture(scope="module")
def hand_mouse():
    scenario = build_scenario("hand-mouse", n_frames=40)
    return scenario, rendered(scenario, range(40))


@needs_mediapipe
def test_footage_mouse_follows_the_true_pole_of_the_flesh_hand(hand_mouse):
    """Frames 0-39: the hand rests, then the index rises to 37 mm (frames 10-35). The base
    stays within 25 mm of the truth, and the raised finger is seen: the estimated height
    over the raised frames averages more than half the truth's."""
    scenario, frames = hand_mouse
    out = list(footage_mouse_frames(scenario.model, iter(frames), scenario.rig,
                                    overlay=False))
    assert [f.index for f in out] == list(range(40))
    truth = PalmMouse.from_start(scenario.model, scenario.states[0]).pole(scenario.states[:40])
    poles = np.array([f.pole for f in out])
    np.testing.assert_allclose(poles[0], 0.0, atol=2.0)  # the start (re-fitted) is the origin
    assert np.abs(poles[:, :2] - truth[:, :2]).max() < 25.0
    raised = truth[:, 2] > 25.0
    assert raised.sum() >= 10
    assert poles[raised, 2].mean() > 0.5 * truth[raised, 2].mean()


@needs_mediapipe
def test_a_video_file_is_read_paced_and_started_by_itself(tmp_path, hand_mouse):
    frames = hand_mouse[1]
    path = tmp_path / "hand.mp4"
    height, width = frames[0][0].shape[:2]
    writer = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*"mp4v"), 10.0, (width, height))
    blank = np.zeros_like(frames[0][0])
    for image in [blank] * 3 + [f[0] for f in frames[:12]]:  # the hand shows in frame 3
        writer.write(cv2.cvtColor(image, cv2.COLOR_RGB2BGR))
    writer.release()
    stream = open_footage_mouse(str(path), fps=1000.0, overlay=True)
    assert stream.model.name == "hand" and "automatic start" in stream.description
    out = list(stream.frames)
    assert [f.index for f in out] == list(range(3, 15))  # numbered as the video's frames
    assert all(f.overlay_jpeg is not None for f in out)


@needs_mediapipe
def test_two_cameras_map_the_hand_at_its_own_size():
    """A flesh hand 0.9 times the model's size before the desk pair: the footage mouse
    measures its size at the start and maps a model of that size (the palm mapping's
    model), so the pole is in the hand's own millimetres."""
    from digiteyes.detect.hand_size import model_hand_length
    from digiteyes.synth.setups import setup_scenario, truth_model

    scenario = setup_scenario("desk", 2, hand_scale=0.9, seed=0, n_frames=3)
    hand = truth_model(scenario)  # the model drawn 0.9 times its size
    frames = [[view.image for view in render_views(hand, scenario.states[t], scenario.rig,
                                                   FLESH, rng=t)]
              for t in range(3)]
    out = list(footage_mouse_frames(scenario.model, iter(frames), scenario.rig,
                                    overlay=False))
    assert len(out) == 3
    mapped = out[0].mapping.model
    assert model_hand_length(mapped) / model_hand_length(scenario.model) == pytest.approx(
        0.9, abs=0.03)


def test_footage_mouse_says_what_is_wrong(tmp_path):
    with pytest.raises(DatasetError, match="no such video file"):
        open_footage_mouse(str(tmp_path / "missing.mp4"))
    with pytest.raises(DatasetError, match="21 hand keypoints"):
        open_footage_mouse(str(tmp_path / "missing.mp4"), model_name="mouse-hand")


@needs_mediapipe
def test_bench_mouse_footage_section_measures_against_the_truth():
    """``digiteyes bench mouse`` section e on 12 frames: the flesh hand is started and
    followed (base within 25 mm), our capsule drawing is reported as it goes (MediaPipe
    does not take it for a hand), and the thesis's set-up beside it holds to a
    millimetre."""
    from digiteyes.benchmarks.mouse import _footage_lines, footage_section

    result = footage_section(12, progress=False)
    rows = {r["appearance"]: r for r in result["rows"]}
    assert set(rows) == {"model", "flesh"}
    flesh = rows["flesh"]
    assert flesh["started"] and flesh["frames_tracked"] == 12 - flesh["start_frame"]
    assert flesh["base_p95_mm"] < 25.0 and len(flesh["pole_mm"]) == flesh["frames_tracked"]
    assert result["thesis_setup"]["height_mean_mm"] < 1.0
    lines = "\n".join(_footage_lines(result))
    assert "flesh" in lines and "thesis set-up" in lines
