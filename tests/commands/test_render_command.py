"""``digiteyes render SCENARIO -o DIR``: datasets with ground truth, clear errors, resume."""

from __future__ import annotations

import numpy as np
import pytest

import digiteyes.synth.sequence
from digiteyes.cli import main
from digiteyes.io.dataset import open_sequence
from digiteyes.kinematics.keypoints import keypoints
from digiteyes.models import model_path
from digiteyes.synth.scenarios import build_scenario


def one_line_error(capsys) -> str:
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("digiteyes: error:"), err
    return err[0]


def test_renders_three_frames_with_ground_truth(tmp_path):
    out = tmp_path / "wh"
    assert main(["render", "whole-hand", "-o", str(out), "--frames", "3", "--seed", "4"]) == 0
    seq = open_sequence(out)
    scenario = build_scenario("whole-hand", seed=4, n_frames=3)
    assert seq.complete and seq.n_frames == 3 and seq.fps == 10.0
    assert seq.camera_names == ["cam0", "cam1"]
    np.testing.assert_array_equal(seq.initial_state, scenario.states[0])
    np.testing.assert_allclose(seq.truth.states, scenario.states, atol=1e-9)
    names, points = keypoints(scenario.model, digiteyes.forward_kinematics(scenario.model,
                                                                           scenario.states))
    assert seq.truth.keypoint_names == names
    np.testing.assert_allclose(seq.truth.keypoints_3d, points, atol=1e-9)
    for c, cam in enumerate(seq.rig):
        np.testing.assert_allclose(seq.truth.keypoints_2d[:, c], cam.project(points), atol=1e-6)
    assert seq.truth.visible.shape == (3, 2, len(names))
    images = seq.frame(2)
    assert all(im.shape == (480, 640) and im.dtype == np.uint8 for im in images)
    assert all(im.max() > 150 for im in images), "the lit hand is in both images"
    assert (out / "model.dh").read_text() == model_path("hand").read_text()
    assert seq.scenario["name"] == "whole-hand" and seq.scenario["seed"] == 4
    assert len(seq.scenario["image_speed_px"]) == 3


def test_existing_folder_needs_force(tmp_path, capsys):
    out = tmp_path / "seq"
    args = ["render", "two-finger-occlusion", "-o", str(out), "--frames", "2"]
    assert main(args) == 0
    capsys.readouterr()
    assert main(args) == 2
    assert "already holds a complete sequence" in one_line_error(capsys)
    assert main([*args, "--force", "--noise", "3"]) == 0
    assert open_sequence(out).scenario["render"]["noise_sigma"] == 3.0


def test_non_empty_folder_without_a_sequence_is_refused(tmp_path, capsys):
    (tmp_path / "notes.txt").write_text("mine")
    assert main(["render", "mouse", "-o", str(tmp_path), "--frames", "1"]) == 2
    assert "not empty" in one_line_error(capsys)
    assert (tmp_path / "notes.txt").read_text() == "mine"


def test_unknown_scenario_is_one_line_listing_the_valid_ones(tmp_path, capsys):
    assert main(["render", "hand-wave", "-o", str(tmp_path / "x")]) == 2
    line = one_line_error(capsys)
    assert "hand-wave" in line and "whole-hand" in line and "two-finger-occlusion" in line
    assert not (tmp_path / "x").exists()


def test_unwritable_folder_is_one_line(tmp_path, capsys):
    blocker = tmp_path / "file"
    blocker.write_text("")
    assert main(["render", "mouse", "-o", str(blocker / "seq"), "--frames", "1"]) == 2
    assert str(blocker / "seq") in one_line_error(capsys)


def test_force_and_resume_exclude_each_other(tmp_path, capsys):
    assert main(["render", "mouse", "-o", str(tmp_path / "s"), "--force", "--resume"]) == 2
    assert "--force and --resume" in one_line_error(capsys)


def test_perturbed_truth_keeps_the_nominal_model_file(tmp_path):
    out = tmp_path / "p"
    assert main(["render", "two-finger-occlusion", "-o", str(out), "--frames", "2",
                 "--perturb", "0.1", "--seed", "2"]) == 0
    seq = open_sequence(out)
    scenario = build_scenario("two-finger-occlusion", seed=2, n_frames=2)
    assert (out / "model.dh").read_text() == model_path("two-finger").read_text()
    np.testing.assert_allclose(seq.truth.states, scenario.states, atol=1e-9)
    nominal = keypoints(scenario.model, digiteyes.forward_kinematics(scenario.model,
                                                                     scenario.states))[1]
    moved = np.linalg.norm(seq.truth.keypoints_3d - nominal, axis=-1)
    assert moved.max() > 2.0, "truth keypoints come from the perturbed hand"
    info = seq.scenario["truth_model"]
    assert info["perturb_model"] == {"model": "two-finger", "link_length": 0.1, "rng": 2}
    truth_model = digiteyes.kinematics.model_from_file(out / info["file"])
    true_keypoints = keypoints(truth_model, digiteyes.forward_kinematics(truth_model,
                                                                         scenario.states))[1]
    np.testing.assert_allclose(seq.truth.keypoints_3d, true_keypoints, atol=1e-9)
    lengths = {n: v["length_mm"] for n, v in info["links"].items() if "length_mm" in v}
    nominal_len = {link.name: link.length for link in scenario.model.links
                   if link.kind == "link"}
    ratios = np.array([lengths[n] / nominal_len[n] for n in nominal_len])
    assert np.all(np.abs(ratios - 1) <= 0.1 + 1e-9) and np.abs(ratios - 1).max() > 0.01


def test_interrupted_render_resumes_to_the_same_dataset(tmp_path, monkeypatch, capsys):
    args = ["--frames", "5", "--noise", "4", "--seed", "3"]
    reference = tmp_path / "ref"
    assert main(["render", "mouse", "-o", str(reference), *args]) == 0

    real = digiteyes.synth.sequence.render_views
    calls = {"n": 0}

    def interrupted(*a, **k):
        calls["n"] += 1
        if calls["n"] == 3:
            raise KeyboardInterrupt
        return real(*a, **k)

    out = tmp_path / "run"
    monkeypatch.setattr(digiteyes.synth.sequence, "render_views", interrupted)
    assert main(["render", "mouse", "-o", str(out), *args]) == 130
    assert "--resume" in capsys.readouterr().err
    partial = open_sequence(out)
    assert not partial.complete and partial.n_frames == 2
    monkeypatch.setattr(digiteyes.synth.sequence, "render_views", real)

    assert main(["render", "mouse", "-o", str(out), "--frames", "5", "--resume"]) == 2
    assert "other settings" in one_line_error(capsys)
    assert main(["render", "mouse", "-o", str(out), *args, "--resume"]) == 0
    done, ref = open_sequence(out), open_sequence(reference)
    assert done.complete and done.n_frames == 5
    for i in range(5):
        np.testing.assert_array_equal(done.frame(i)[0], ref.frame(i)[0])
    np.testing.assert_array_equal(done.truth.keypoints_2d, ref.truth.keypoints_2d)
    np.testing.assert_array_equal(done.truth.states, ref.truth.states)


@pytest.mark.parametrize("option", [["--noise", "-1"], ["--perturb", "1.5"],
                                    ["--frames", "0"]])
def test_bad_option_values_are_refused(tmp_path, option):
    assert main(["render", "mouse", "-o", str(tmp_path / "s"), *option]) == 2
    assert not (tmp_path / "s").exists()


def test_video_output(tmp_path):
    out = tmp_path / "v"
    assert main(["render", "two-finger-occlusion", "-o", str(out), "--frames", "3",
                 "--video"]) == 0
    seq = open_sequence(out)
    assert seq.frames_spec["kind"] == "video" and seq.n_frames == 3
    assert seq.frame(2)[0].shape[:2] == (480, 640)
