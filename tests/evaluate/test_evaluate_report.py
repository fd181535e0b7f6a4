"""Reports: strict-JSON metrics, a markdown summary and the PNG plots it links."""

from __future__ import annotations

import json
import re

import cv2
import numpy as np

from digiteyes.evaluate import evaluate_run, headline_rows, write_report
from digiteyes.io import GroundTruth


def _strict(text):
    def refuse(name):
        raise ValueError(f"non-standard JSON constant {name}")

    return json.loads(text, parse_constant=refuse)


def test_report_writes_metrics_markdown_and_plots(tmp_path, hand, rig, make_trajectory,
                                                  make_truth, make_log):
    states = make_trajectory(hand, 12, seed=2)
    truth = make_truth(hand, rig, states)
    est = states.copy()
    est[:, 9] += 0.05
    log = make_log(est, lost=np.arange(12) == 9)
    log.residual_rms_px[3] = np.nan
    metrics = evaluate_run(log, truth, hand, rig)
    report = write_report(metrics, log, truth, hand, tmp_path / "out", fps=30.0)
    assert report == tmp_path / "out" / "report.md"
    saved = _strict((tmp_path / "out" / "metrics.json").read_text())
    assert saved["track_life"]["frames"] == 9
    assert saved["per_frame"]["residual_rms_px"][3] is None
    assert saved["joint_angle_error_deg"]["per_state"]["index.pip"]["max_abs"] == \
        metrics["joint_angle_error_deg"]["per_state"]["index.pip"]["max_abs"]
    text = report.read_text()
    images = re.findall(r"!\[[^]]*\]\(([^)]+)\)", text)
    assert set(images) == {"fingertip_error.png", "trajectory-palm.png", "trajectory-joints.png",
                           "joint_angle_error.png"}
    for name in images:
        image = cv2.imread(str(tmp_path / "out" / name))
        assert image is not None and image.shape[0] > 100
    for label, value in headline_rows(metrics):
        assert f"| {label} | {value} |" in text
    assert "index.tip" in text and "thumb.ip" in text


def test_report_of_marker_truth_has_no_state_plots_of_truth(tmp_path, hand, rig,
                                                            make_trajectory, make_truth,
                                                            make_log):
    states = make_trajectory(hand, 6, seed=3)
    truth = make_truth(hand, rig, states)
    markers = GroundTruth(None, truth.keypoint_names, truth.keypoints_3d, truth.keypoints_2d,
                          truth.visible)
    log = make_log(states)
    metrics = evaluate_run(log, markers, hand, rig)
    report = write_report(metrics, log, markers, hand, tmp_path)
    text = report.read_text()
    assert "joint_angle_error.png" not in text
    assert "joint angle error" not in text
    assert (tmp_path / "fingertip_error.png").is_file()
