"""Evaluation against ground truth: accuracy metrics, track life and reports.

See docs/evaluation.md for the definition of every metric.
"""

from digiteyes.evaluate.metrics import (
    DEFAULT_LOSS_THRESHOLD_MM,
    evaluate_run,
    joint_angle_states,
    palm_pose,
    quaternion_angle,
)
from digiteyes.evaluate.report import headline_rows, write_report

__all__ = [
    "DEFAULT_LOSS_THRESHOLD_MM", "evaluate_run", "headline_rows", "joint_angle_states",
    "palm_pose", "quaternion_angle", "write_report",
]
