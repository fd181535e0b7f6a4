"""``digiteyes evaluate RESULT_DIR GT_DIR``: table, report files, clear mismatch errors."""

from __future__ import annotations

import numpy as np
import pytest

from digiteyes.cli import main
from digiteyes.io import FrameTruth, SequenceWriter, StateLogWriter
from digiteyes.kinematics import load_model

N = 8


@pytest.fixture
def dataset(tmp_path, hand, rig, make_trajectory, make_truth):
    states = make_trajectory(hand, N, seed=5)
    truth = make_truth(hand, rig, states)
    blank = [np.zeros((cam.height, cam.width), np.uint8) for cam in rig.cameras]
    with SequenceWriter(tmp_path / "gt", hand, rig, states[0], 10.0) as writer:
        for i in range(N):
            writer.write_frame(blank, FrameTruth(states[i], truth.keypoint_names,
                                                 truth.keypoints_3d[i], truth.keypoints_2d[i],
                                                 truth.visible[i]))
    return tmp_path / "gt", states


def write_log(path, model, states, frames=None):
    with StateLogWriter(path, model) as log:
        for i, q in zip(frames if frames is not None else range(len(states)), states,
                        strict=True):
            log.append(i, q, time_s=0.05, lost=False, residual_rms_px=0.7, iterations=4)


def test_evaluate_prints_table_and_writes_report(tmp_path, hand, dataset, capsys):
    gt, states = dataset
    est = states.copy()
    est[:, 4] += 6.0
    write_log(tmp_path / "run" / "states.csv", hand, est)
    assert main(["evaluate", str(tmp_path / "run"), str(gt)]) == 0
    out = capsys.readouterr().out
    assert "fingertip error mean / median / max   6.00 / 6.00 / 6.00 mm" in out
    assert f"track life                            {N} of {N} frames" in out
    for name in ("metrics.json", "report.md", "trajectory-palm.png"):
        assert (tmp_path / "run" / "evaluation" / name).is_file()
    assert main(["evaluate", str(tmp_path / "run" / "states.csv"), str(gt), "-o",
                 str(tmp_path / "elsewhere"), "--loss-threshold-mm", "5"]) == 0
    assert "track life                            0 of 8 frames" in capsys.readouterr().out
    assert (tmp_path / "elsewhere" / "report.md").is_file()


def test_evaluate_refuses_mismatched_runs(tmp_path, hand, dataset, capsys):
    gt, states = dataset
    mouse = load_model("mouse-hand")
    write_log(tmp_path / "mouse" / "states.csv", mouse, np.tile(mouse.neutral(), (3, 1)))
    assert main(["evaluate", str(tmp_path / "mouse"), str(gt)]) == 2
    assert "not a log of model 'hand'" in capsys.readouterr().err
    write_log(tmp_path / "long" / "states.csv", hand, np.vstack([states, states[:2]]))
    assert main(["evaluate", str(tmp_path / "long"), str(gt)]) == 2
    assert f"frame {N}, beyond the ground truth" in capsys.readouterr().err
    assert main(["evaluate", str(gt), str(gt)]) == 2
    assert "no such state log" in capsys.readouterr().err


def test_evaluate_needs_ground_truth(tmp_path, hand, rig, capsys):
    with SequenceWriter(tmp_path / "nogt", hand, rig, hand.neutral(), 10.0) as writer:
        writer.write_frame([np.zeros((c.height, c.width), np.uint8) for c in rig.cameras])
    write_log(tmp_path / "run" / "states.csv", hand, hand.neutral()[None])
    assert main(["evaluate", str(tmp_path / "run"), str(tmp_path / "nogt")]) == 2
    assert "has no ground truth" in capsys.readouterr().err
