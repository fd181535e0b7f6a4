"""Metrics against hand-made cases with known answers."""

from __future__ import annotations

import cv2
import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from digiteyes.errors import DatasetError
from digiteyes.evaluate import evaluate_run, joint_angle_states, quaternion_angle
from digiteyes.io import GroundTruth
from digiteyes.kinematics.rotations import quaternion_from_rotvec, quaternion_multiply

N = 30


@pytest.fixture
def hand_case(hand, rig, make_trajectory, make_truth):
    states = make_trajectory(hand, N, seed=1)
    return states, make_truth(hand, rig, states)


def test_identical_states_give_zero_errors(hand, rig, hand_case, make_log):
    states, truth = hand_case
    m = evaluate_run(make_log(states), truth, hand, rig)
    for key in ("fingertip_error_mm", "keypoint_error_mm", "reprojection_error_px"):
        assert m[key]["max"] == pytest.approx(0.0, abs=1e-9), key
    assert m["joint_angle_error_deg"]["max_abs"] == 0.0
    assert m["palm"]["position_error_mm"]["max"] == 0.0
    assert m["palm"]["orientation_error_deg"]["max"] == pytest.approx(0.0, abs=1e-6)
    assert m["track_life"] == {"frames": N, "of_frames": N, "lost_at_frame": None,
                               "reason": None, "threshold_mm": 20.0,
                               "measure": "mean fingertip error"}
    assert set(m["fingertip_error_mm"]["per_tip"]) == {
        "index.tip", "middle.tip", "ring.tip", "little.tip", "thumb.tip"}
    assert len(m["per_frame"]["frame"]) == N


def test_palm_translation_offset_is_the_position_error(hand, rig, hand_case, make_log):
    states, truth = hand_case
    est = states.copy()
    est[:, 4:7] += (3.0, 4.0, 0.0)
    m = evaluate_run(make_log(est), truth, hand, rig)
    assert m["palm"]["source"] == "pose states"
    for stat in ("mean", "median", "max"):
        assert m["palm"]["position_error_mm"][stat] == pytest.approx(5.0, abs=1e-12)
        # a pure translation moves every keypoint by the same 5 mm
        assert m["fingertip_error_mm"][stat] == pytest.approx(5.0, abs=1e-9)
        assert m["keypoint_error_mm"][stat] == pytest.approx(5.0, abs=1e-9)
    assert m["palm"]["orientation_error_deg"]["max"] == pytest.approx(0.0, abs=1e-6)
    assert m["joint_angle_error_deg"]["rms"] == 0.0
    # reprojection error against OpenCV's projection of the shifted keypoints
    errors = []
    for c, cam in enumerate(rig.cameras):
        rvec = cv2.Rodrigues(cam.T_cam_world[:3, :3])[0]
        for t in range(N):
            kp = truth.keypoints_3d[t] + (3.0, 4.0, 0.0)
            w = cv2.projectPoints(kp, rvec, cam.T_cam_world[:3, 3], cam.K, cam.dist)[0][:, 0]
            err = np.linalg.norm(w - truth.keypoints_2d[t, c], axis=1)
            errors.append(err[truth.visible[t, c]])
    errors = np.concatenate(errors)
    assert m["reprojection_error_px"]["mean"] == pytest.approx(errors.mean(), rel=1e-9)
    assert m["reprojection_error_px"]["max"] == pytest.approx(errors.max(), rel=1e-9)


@pytest.mark.parametrize("sign", [1.0, -1.0])
def test_ten_degree_rotation_is_the_orientation_error(hand, rig, hand_case, make_log, sign):
    states, truth = hand_case
    axis = np.array([1.0, -2.0, 0.5]) / np.linalg.norm([1.0, -2.0, 0.5])
    turn = quaternion_from_rotvec(np.radians(10.0) * axis)
    est = states.copy()
    est[:, 0:4] = sign * quaternion_multiply(turn, states[:, 0:4])
    m = evaluate_run(make_log(est), truth, hand, rig)
    orientation = np.array(m["per_frame"]["palm_orientation_error_deg"])
    np.testing.assert_allclose(orientation, 10.0, atol=1e-9)
    assert m["palm"]["position_error_mm"]["max"] == 0.0
    assert m["fingertip_error_mm"]["mean"] > 1.0


def test_five_degree_offset_on_one_joint(hand, rig, hand_case, make_log):
    states, truth = hand_case
    est = states.copy()
    pip = hand.state_index("index.pip")
    est[:, pip] += np.radians(5.0) + 2.0 * np.pi  # a full turn more is the same angle
    m = evaluate_run(make_log(est), truth, hand, rig)
    angles = m["joint_angle_error_deg"]
    n_joints = len(joint_angle_states(hand))
    assert n_joints == 21
    assert angles["rms"] == pytest.approx(np.sqrt(25.0 / n_joints), rel=1e-9)
    assert angles["mean_abs"] == pytest.approx(5.0 / n_joints, rel=1e-9)
    assert angles["max_abs"] == pytest.approx(5.0, rel=1e-9)
    assert angles["per_finger"]["index"]["rms"] == pytest.approx(np.sqrt(25.0 / 4), rel=1e-9)
    assert angles["per_finger"]["index"]["mean_abs"] == pytest.approx(1.25, rel=1e-9)
    assert angles["per_finger"]["middle"]["rms"] == 0.0
    assert list(angles["per_finger"]) == ["index", "middle", "ring", "little", "thumb"]
    assert angles["per_joint_type"]["pip"]["rms"] == pytest.approx(2.5, rel=1e-9)
    assert angles["per_joint_type"]["mcp"]["rms"] == 0.0
    assert {"abd", "mcp", "pip", "dip", "thumb.ip"} <= set(angles["per_joint_type"])
    assert angles["per_state"]["index.pip"]["rms"] == pytest.approx(5.0, rel=1e-9)
    assert "palm.qw" not in angles["per_state"]
    series = np.array(m["per_frame"]["joint_angle_error_deg_rms"])
    np.testing.assert_allclose(series, np.sqrt(25.0 / n_joints), rtol=1e-9)
    assert m["palm"]["position_error_mm"]["max"] == 0.0


def test_track_life_ends_at_the_first_lost_frame(hand, rig, hand_case, make_log):
    states, truth = hand_case
    lost = np.zeros(N, bool)
    lost[[12, 20]] = True
    m = evaluate_run(make_log(states, lost=lost), truth, hand, rig)
    assert (m["track_life"]["frames"], m["track_life"]["lost_at_frame"]) == (12, 12)
    assert m["track_life"]["reason"] == "flagged lost"
    assert m["run"]["lost_frames"] == 2
    # a log that starts later counts its track life from its first frame
    m = evaluate_run(make_log(states[5:], lost=lost[5:], frames=np.arange(5, N)), truth, hand,
                     rig)
    assert (m["track_life"]["frames"], m["track_life"]["lost_at_frame"]) == (7, 12)


def test_track_life_ends_when_fingertip_error_exceeds_threshold(hand, rig, hand_case,
                                                                make_log):
    states, truth = hand_case
    est = states.copy()
    est[17:, 4] += 25.0  # every keypoint 25 mm off from frame 17 on
    m = evaluate_run(make_log(est), truth, hand, rig)
    assert (m["track_life"]["frames"], m["track_life"]["lost_at_frame"]) == (17, 17)
    assert "fingertip error > 20 mm" in m["track_life"]["reason"]
    assert m["fingertip_error_mm"]["within_track_life"]["max"] == pytest.approx(0.0, abs=1e-9)
    m = evaluate_run(make_log(est), truth, hand, rig, loss_threshold_mm=30.0)
    assert m["track_life"]["frames"] == N


def test_truth_without_keypoints_uses_the_true_states(hand, rig, hand_case, make_log):
    states, truth = hand_case
    est = states.copy()
    est[:, 8:12] += 0.1
    full = evaluate_run(make_log(est), truth, hand, rig)
    only_states = GroundTruth(truth.states, (), np.zeros((N, 0, 3)), np.zeros((N, 2, 0, 2)),
                              np.zeros((N, 2, 0), bool))
    derived = evaluate_run(make_log(est), only_states, hand, rig)
    for key in ("fingertip_error_mm", "keypoint_error_mm", "reprojection_error_px"):
        for stat in ("mean", "max"):
            assert derived[key][stat] == pytest.approx(full[key][stat], rel=1e-12)


def test_truth_of_keypoints_only_skips_angle_and_palm(hand, rig, hand_case, make_log):
    states, truth = hand_case
    keep = [i for i, k in enumerate(truth.keypoint_names) if k.endswith(".tip")]
    markers = GroundTruth(None, tuple(truth.keypoint_names[i] for i in keep),
                          truth.keypoints_3d[:, keep], truth.keypoints_2d[:, :, keep],
                          truth.visible[:, :, keep])
    est = states.copy()
    est[:, 4] += 2.0
    m = evaluate_run(make_log(est), markers, hand, rig)
    assert m["joint_angle_error_deg"] is None and m["palm"] is None
    assert m["fingertip_error_mm"]["mean"] == pytest.approx(2.0, abs=1e-9)
    assert set(m["keypoint_error_mm"]["per_keypoint"]) == set(markers.keypoint_names)


def test_mouse_hand_palm_on_prismatic_joints(mouse_hand, rig, make_trajectory, make_truth,
                                             make_log):
    states = make_trajectory(mouse_hand, 10, seed=4)
    truth = make_truth(mouse_hand, rig, states)
    est = states.copy()
    est[:, mouse_hand.state_index("palm.x")] += 3.0
    est[:, mouse_hand.state_index("palm.y")] -= 4.0
    est[:, mouse_hand.state_index("palm.rot")] += np.radians(10.0)
    m = evaluate_run(make_log(est), truth, mouse_hand, rig)
    assert m["palm"]["source"] == "palm frame"
    np.testing.assert_allclose(m["per_frame"]["palm_position_error_mm"], 5.0, atol=1e-9)
    np.testing.assert_allclose(m["per_frame"]["palm_orientation_error_deg"], 10.0, atol=1e-9)
    # palm.rot moves the palm, so it is not a joint angle
    assert "palm.rot" not in m["joint_angle_error_deg"]["per_state"]
    assert m["joint_angle_error_deg"]["max_abs"] == 0.0


def test_mismatches_raise_dataset_error(hand, rig, hand_case, make_log):
    states, truth = hand_case
    with pytest.raises(DatasetError, match=r"frame 30, beyond the ground truth \(frames 0..29\)"):
        evaluate_run(make_log(states, frames=np.arange(1, N + 1)), truth, hand, rig)
    with pytest.raises(DatasetError, match="must increase"):
        evaluate_run(make_log(states, frames=np.r_[np.arange(N - 1), 3]), truth, hand, rig)
    bad = GroundTruth(truth.states, ("index.tip", "elbow"), truth.keypoints_3d[:, :2],
                      truth.keypoints_2d[:, :, :2], truth.visible[:, :, :2])
    with pytest.raises(DatasetError, match="elbow"):
        evaluate_run(make_log(states), bad, hand, rig)


def test_quaternion_angle_matches_scipy_and_ignores_sign():
    rng = np.random.default_rng(7)
    q1, q2 = rng.normal(size=(2, 200, 4))
    scale = rng.uniform(0.5, 2.0, (200, 1))
    expected = (Rotation.from_quat(q1[:, [1, 2, 3, 0]]).inv()
                * Rotation.from_quat(q2[:, [1, 2, 3, 0]])).magnitude()
    np.testing.assert_allclose(quaternion_angle(q1, q2), expected, atol=1e-12)
    np.testing.assert_allclose(quaternion_angle(-scale * q1, q2), expected, atol=1e-12)
    assert quaternion_angle(q1[0], q1[0]) == 0.0


def test_the_logs_hand_scale_sizes_the_estimated_hand(hand, rig, make_trajectory,
                                                      make_truth, make_log):
    """Truth drawn from a hand 0.9 times the model's: a log of the true states at the
    model's size is off at the fingertips by a tenth of their distance from the palm; the
    same log with ``hand_scale`` 0.9 is exact."""
    from dataclasses import replace

    from digiteyes.kinematics.scaling import scaled_model

    small = scaled_model(hand, 0.9)
    states = make_trajectory(hand, N, seed=2)
    truth = make_truth(small, rig, states)
    log = make_log(states)
    off = evaluate_run(log, truth, hand, rig)["fingertip_error_mm"]["mean"]
    exact = evaluate_run(replace(log, hand_scale=np.full(N, 0.9)), truth, hand, rig)
    assert off > 5.0
    assert exact["fingertip_error_mm"]["max"] == pytest.approx(0.0, abs=1e-9)
    assert exact["reprojection_error_px"]["max"] == pytest.approx(0.0, abs=1e-6)
