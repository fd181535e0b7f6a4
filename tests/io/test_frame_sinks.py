"""The per-frame sinks draw the hand at the size the tracker reports."""

from __future__ import annotations

import csv
import json

import numpy as np

from digiteyes.camera import Rig
from digiteyes.camera.default import default_camera
from digiteyes.io.frame_sinks import CameraKeypoints, KeypointLog, frame_message
from digiteyes.kinematics import forward_kinematics, load_model
from digiteyes.kinematics.keypoints import keypoints
from digiteyes.kinematics.scaling import scaled_model
from digiteyes.synth.scenarios import build_scenario
from digiteyes.trackers import TrackResult


def test_keypoints_of_a_result_are_those_of_the_hand_of_its_size(tmp_path):
    """A result of a hand 0.9 times the model's: the JSON line and ``keypoints.csv`` give
    the points of ``scaled_model(model, 0.9)`` at the result's state, in the camera frame
    and in pixels, and the line names the size."""
    scenario = build_scenario("desk-2cam", seed=0, n_frames=1)
    model, rig, q = scenario.model, scenario.rig, scenario.states[0]
    result = TrackResult(q, 0.0, 1.0, False, "", 1, hand_scale=0.9)
    small = scaled_model(model, 0.9)
    names, world = keypoints(small, forward_kinematics(small, q))
    message = json.loads(json.dumps(frame_message(CameraKeypoints(model, rig), 7, result,
                                                 False)))
    assert message["hand_scale"] == 0.9
    log = KeypointLog(tmp_path / "keypoints.csv", CameraKeypoints(model, rig))
    log.write(7, [], result, False)
    log.close()
    with open(tmp_path / "keypoints.csv", newline="", encoding="utf-8") as handle:
        row = next(csv.DictReader(handle))
    for camera in rig:
        got = message["keypoints"][camera.name]
        xyz = np.array([got[n]["xyz_mm"] for n in names])
        uv = np.array([got[n]["uv_px"] for n in names])
        np.testing.assert_allclose(xyz, camera.to_camera(world[0]), atol=0.006)
        np.testing.assert_allclose(uv, camera.project(world[0]), atol=0.006)
        tip = names.index("index.tip")
        np.testing.assert_allclose([float(row[f"{camera.name}.index.tip.{a}"])
                                    for a in ("x_mm", "y_mm", "z_mm")], xyz[tip], atol=0.006)


def test_the_same_frames_keypoints_are_computed_once(monkeypatch):
    """The keypoint log and the stream ask one run's keypoints object for a frame's
    keypoints in turn: the second call returns the first's arrays; another state or
    scale computes anew."""
    model = load_model("hand")
    keypoints = CameraKeypoints(model, Rig((default_camera(640, 480),)))
    calls = []
    compute = keypoints._compute
    monkeypatch.setattr(keypoints, "_compute", lambda *a: calls.append(a) or compute(*a))
    q = model.neutral()
    q[6] = 400.0
    first = keypoints(q, 1.0)
    assert keypoints(q.copy(), 1.0) is first
    assert len(calls) == 1
    assert keypoints(q, 0.9) is not first
    moved = q.copy()
    moved[6] += 1.0
    keypoints(moved, 0.9)
    assert len(calls) == 3
