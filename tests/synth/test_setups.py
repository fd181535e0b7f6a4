"""Camera setups, hand sizes and the CyberGlove scenario family."""

from __future__ import annotations

import numpy as np
import pytest

from digiteyes.errors import DigitEyesError
from digiteyes.kinematics import forward_kinematics, load_model
from digiteyes.kinematics.keypoints import keypoints
from digiteyes.synth.perturb import scale_model
from digiteyes.synth.scenarios import SCENARIOS, build_scenario
from digiteyes.synth.setups import SETUPS, setup_scenario, truth_model


@pytest.mark.parametrize("setup", SETUPS)
@pytest.mark.parametrize("n_cameras", [1, 2])
def test_setups_keep_the_hand_inside_every_image(setup, n_cameras):
    scenario = build_scenario(f"{setup}-{n_cameras}cam", seed=2)
    assert len(scenario.rig) == n_cameras and scenario.n_frames == 160
    _, points = keypoints(scenario.model, forward_kinematics(scenario.model, scenario.states))
    for cam in scenario.rig.cameras:
        pixels = cam.project(points.reshape(-1, 3))
        assert np.all(cam.depth(points.reshape(-1, 3)) > 200.0)
        assert np.all(cam.in_image(pixels)), (setup, cam.name)


def test_desk_fingers_curl_in_turn():
    scenario = build_scenario("desk-1cam", seed=0)
    model = scenario.model
    mcp = np.stack([scenario.states[:, model.state_index(f"{f}.mcp")]
                    for f in ("index", "middle", "ring", "little")], axis=1)
    peaks = np.argmax(mcp[:160], axis=0)
    assert np.all(np.diff(peaks) > 0)  # index first, little last
    assert np.degrees(mcp.max(axis=0)).min() > 40.0


def test_scale_model_scales_keypoints_and_truth_model():
    hand = load_model("hand")
    q = hand.neutral()
    _, base = keypoints(hand, forward_kinematics(hand, q))
    _, small = keypoints(scale_model(hand, 0.8), forward_kinematics(scale_model(hand, 0.8), q))
    assert np.allclose(small, 0.8 * base)
    scenario = setup_scenario("webcam", 1, hand_scale=1.15, seed=0, n_frames=5)
    assert scenario.model.name == hand.name
    assert truth_model(scenario).links[1].length == pytest.approx(1.15 * hand.links[1].length)
    with pytest.raises(DigitEyesError, match="hand_scale"):
        setup_scenario("desk", 1, hand_scale=1.4)
    with pytest.raises(DigitEyesError, match="setup"):
        setup_scenario("ceiling")


def test_glove_family_is_registered_and_reads_real_data_or_fails_clearly(monkeypatch):
    from digiteyes.synth import glove

    assert {"glove-desk-1cam", "glove-egocentric-2cam"} <= set(SCENARIOS)
    monkeypatch.setenv("DIGITEYES_GLOVE_DIR", "/nonexistent")
    with pytest.raises(DigitEyesError, match="CyberGlove data not found"):
        glove.glove_dir("/nonexistent/glove")


def test_glove_mapping_on_the_real_recordings():
    from digiteyes.synth import glove

    try:
        glove.glove_dir()
    except DigitEyesError:
        pytest.skip("CyberGlove data (../shared/data/glove) not present")
    times, angles = glove.load_glove(0, 0)
    assert angles.shape[1] == 23 and np.all(np.diff(times) > 0)
    hand = load_model("hand")
    q = glove.glove_to_states(hand, angles)
    assert np.all(q >= hand.lower - 1e-12) and np.all(q <= hand.upper + 1e-12)
    # grasping flexes the fingers: the index MCP spans tens of degrees
    assert np.ptp(np.degrees(q[:, hand.state_index("index.mcp")])) > 20.0
    scenario = build_scenario("glove-webcam-2cam", seed=8, n_frames=30)
    assert scenario.n_frames == 30 and "subject 1 trial 1" in scenario.metadata["motion"]
