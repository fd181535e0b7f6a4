"""The tracker benchmark on tiny inputs: its pieces, and a whole run of a few frames."""

import json
import math
from dataclasses import replace

import numpy as np
import pytest

from digiteyes.apps.mouse3d import pole_from_state
from digiteyes.benchmarks import tracker as bench
from digiteyes.io import StateLog
from digiteyes.synth.scenarios import build_scenario
from digiteyes.trackers import FeatureTrackerOptions

RUN_KEYS = ("fingertip_err_mm_mean", "joint_angle_err_deg_rms", "palm_pos_err_mm_mean",
            "palm_rot_err_deg_mean", "track_life_frames", "frames", "lost_frames")


@pytest.fixture(scope="module")
def whole_hand():
    return bench.render_sequence(build_scenario("whole-hand", seed=0, n_frames=5))


def test_camera_subset(whole_hand):
    mono = whole_hand.cameras((0,))
    assert len(mono.rig) == 1 and mono.rig.cameras[0] is whole_hand.rig.cameras[0]
    assert all(len(frame) == 1 for frame in mono.images)
    np.testing.assert_array_equal(mono.images[3][0], whole_hand.images[3][0])
    n, k = whole_hand.n_frames, len(whole_hand.truth.keypoint_names)
    assert mono.truth.keypoints_2d.shape == (n, 1, k, 2)
    np.testing.assert_array_equal(mono.truth.visible[:, 0], whole_hand.truth.visible[:, 0])
    assert whole_hand.cameras(None) is whole_hand


def test_stage_split_and_accuracy_of_a_short_run(whole_hand):
    outcome = bench.track_sequence(whole_hand, FeatureTrackerOptions(iterations_per_frame=2))
    assert outcome.iterations == 2 * whole_hand.n_frames
    mono = bench.track_sequence(whole_hand.cameras((0,)), FeatureTrackerOptions())
    # every feature is asked for in both cameras
    assert mono.features_per_frame > 0
    assert outcome.features_per_frame == 2 * mono.features_per_frame
    ms = bench.per_iteration_ms(outcome)
    assert all(ms[stage] > 0 for stage in bench.STAGES)
    # the stage timers sit inside step(): together they cannot exceed its total
    assert 0 <= ms["other"] < ms["total"]
    assert ms["state_estimation"] == pytest.approx(ms["jacobian"] + ms["linear_solve"])
    assert ms["total_with_shading"] == pytest.approx(
        1e3 * outcome.tracker_seconds / outcome.iterations)
    # the shading prediction is once per frame, outside the iterations' total
    shading = outcome.stage_seconds["shading"]
    assert shading > 0
    assert ms["shading_per_frame"] == pytest.approx(1e3 * shading / whole_hand.n_frames)
    assert ms["total"] == pytest.approx(ms["total_with_shading"]
                                        - 1e3 * shading / outcome.iterations)

    summary = bench.accuracy_summary(whole_hand, outcome)
    for key in RUN_KEYS:
        assert math.isfinite(summary[key]), key
    assert summary["frames"] == whole_hand.n_frames
    # tracked from the true first state on black cloth with two cameras: close to truth
    assert summary["fingertip_err_mm_mean"] < 5.0
    assert summary["track_life_frames"] == whole_hand.n_frames


def test_rim_shading_biases_the_measured_widths(whole_hand):
    """Section (e)'s diagnosis: measured at the true states, link widths come out narrower
    under Lambert shading (darker towards the silhouette) than under flat shading, where
    they match the model."""
    scenario = whole_hand.scenario
    flat = bench.render_sequence(scenario, flat=True, cameras=(0,))
    assert len(flat.rig) == 1 and flat.rig.cameras[0] is whole_hand.rig.cameras[0]
    assert flat.truth.keypoints_2d.shape[1] == 1
    lambert = bench.width_bias(whole_hand, every=1)
    even = bench.width_bias(flat, every=1)
    assert abs(even["width_bias_px_mean"]) < 0.1 and even["width_bias_px_link_rms"] < 0.2
    assert lambert["width_bias_px_mean"] < even["width_bias_px_mean"] - 0.2
    assert lambert["width_bias_px_link_rms"] > 2 * even["width_bias_px_link_rms"]


def test_pole_error_uses_the_true_hand():
    scenario = build_scenario("mouse", seed=0, n_frames=45)
    scenario = replace(scenario, states=scenario.states[36:40])  # the index finger is up
    sequence = bench.render_sequence(scenario, perturbed=True)
    n, model = sequence.n_frames, scenario.model
    states = np.array(scenario.states)
    # an "estimate" equal to the true states: the pole error is the model's error only
    log = StateLog(np.arange(n), states, np.zeros(n, bool), np.zeros(n), np.ones(n, int),
                   np.full(n, 1e-3))
    outcome = bench.TrackOutcome(log, dict.fromkeys(bench.STAGES, 0.0), 3e-3, n, 1.0)
    summary = bench.accuracy_summary(sequence, outcome, pole=True)
    expected = np.mean(np.abs(pole_from_state(model, states)[:, 2]
                              - pole_from_state(sequence.truth_model, states)[:, 2]))
    assert expected > 0.1
    assert summary["pole_height_err_mm_mean"] == pytest.approx(expected)


def test_choose_iterations_stops_at_the_first_run_that_meets_the_targets():
    figures = {1: (15.0, 5.4), 2: (9.0, 4.0), 3: (7.9, 4.9), 4: (6.0, 3.0), 5: (6.0, 3.0)}
    calls = []

    def track_at(k):
        calls.append(k)
        tip, angle = figures[k]
        return {"fingertip_err_mm_mean": tip, "joint_angle_err_deg_rms": angle}

    k, met, runs = bench.choose_iterations(track_at)
    assert (k, met, calls, list(runs)) == (3, True, [1, 2, 3, 5], [1, 2, 3, 5])
    figures[3] = (8.1, 4.0)
    calls.clear()
    assert bench.choose_iterations(track_at)[:2] == (4, True)
    figures.update({4: (None, 1.0), 5: (9.0, 6.0)})
    calls.clear()
    k, met, runs = bench.choose_iterations(track_at)
    assert (k, met, calls) == (bench.DEFAULT_ITERATIONS, False, [1, 2, 3, 4, 5])
    assert runs[5]["fingertip_err_mm_mean"] == 9.0


def test_tiny_run_writes_finite_json(monkeypatch, tmp_path, capsys):
    tiny = bench.Settings(frames=3, speed_frames=2, e2e_frames=3,
                          ablations=(bench.QUICK_ABLATIONS[0], "1 iteration"), speed_passes=1)
    monkeypatch.setattr(bench, "QUICK", tiny)
    path = tmp_path / "tracker.json"
    result = bench.run(json_path=str(path), quick=True, progress=False)
    stored = json.loads(path.read_text(encoding="utf-8"))
    assert stored["ms_per_iteration_mono"] == pytest.approx(result["ms_per_iteration_mono"])
    for key in ("ms_per_iteration_mono", "ms_per_iteration_stereo", "fps_end_to_end",
                "fps_end_to_end_overlay", "speedup_vs_thesis_stereo"):
        assert math.isfinite(stored[key]) and stored[key] > 0, key
    k = stored["fps_end_to_end_iterations"]
    runs = stored["e2e_runs"]
    assert str(k) in runs and stored["fps_end_to_end"] == runs[str(k)]["fps"]
    assert stored["targets_met"] == bench.meets_targets(runs[str(k)], bench.MONO_TARGETS)
    assert stored["kb_per_frame"] < stored["kb_per_frame_crf12"]
    for suffix in ("", "_crf12", "_ffv1"):
        assert stored[f"fps_end_to_end{suffix}"] > 0
    for label in ("mono", "stereo"):
        stages = stored[f"per_iteration_{label}"]
        assert set(bench.STAGES) <= set(stages)
    assert set(stored["accuracy"]) == set(bench.ACCURACY_CASES)
    for case, by_background in stored["accuracy"].items():
        for by_model in by_background.values():
            assert set(by_model) == set(bench.MODELS)
            for summary in by_model.values():
                assert all(math.isfinite(summary[k]) for k in RUN_KEYS), case
                assert ("pole_height_err_mm_mean" in summary) == (case == "mouse")
    assert set(stored["ablations"]) == set(tiny.ablations)
    assert set(stored["shading"]) == {"lambert", "flat"}
    for by_shading in stored["shading"].values():
        assert math.isfinite(by_shading["width_bias_px_mean"])
        for label in ("corrected", "with_width", "without_width"):
            assert all(math.isfinite(by_shading[label][k]) for k in RUN_KEYS)
    out = capsys.readouterr().out
    assert "machine:" in out
    for section in ("(a)", "(b)", "(c)", "(d)", "(e)"):
        assert section in out
