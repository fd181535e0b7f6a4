"""``digiteyes render --appearance flesh --hand-scale F``: an independent, resized truth."""

from __future__ import annotations

import numpy as np

import digiteyes.synth
from digiteyes.cli import main
from digiteyes.io.dataset import open_sequence
from digiteyes.kinematics import load_model
from digiteyes.kinematics.keypoints import keypoints
from digiteyes.models import model_path
from digiteyes.synth.perturb import scale_model
from digiteyes.synth.scenarios import build_scenario


def test_flesh_render_of_a_smaller_hand(tmp_path):
    out = tmp_path / "web"
    assert main(["render", "webcam-1cam", "-o", str(out), "--frames", "2", "--appearance",
                 "flesh", "--hand-scale", "0.9", "--skin-tone", "light"]) == 0
    seq = open_sequence(out)
    scenario = build_scenario("webcam-1cam", seed=0, n_frames=2)
    np.testing.assert_allclose(seq.truth.states, scenario.states, atol=1e-9)
    assert (out / "model.dh").read_text() == model_path("hand").read_text()
    truth = scale_model(load_model("hand"), 0.9)
    _, points = keypoints(truth, digiteyes.forward_kinematics(truth, scenario.states))
    np.testing.assert_allclose(seq.truth.keypoints_3d, points, atol=1e-9)
    assert load_model(out / "truth" / "model.dh").links[1].length == truth.links[1].length
    render = seq.scenario["render"]
    assert render["appearance"] == "flesh" and render["hand_scale"] == 0.9
    image = seq.frame(1)[0]
    assert image.shape == (480, 640) and (image > 40).sum() > 5000  # the hand is drawn
    assert seq.truth.visible[:, 0].sum() > 10
