"""Accuracy of a tracker run against ground truth (DESIGN §7, thesis §4.1).

:func:`evaluate_run` compares a state log with a sequence's ground truth and returns a
plain dict (JSON-ready) of headline numbers and per-frame series; docs/evaluation.md defines
every entry. Units: millimetres, degrees, pixels, frames.

Keypoints of the estimated states are computed exactly as the renderer computes the true
ones, through a keypoint function ``keypoint_fn(model, kin) -> (names, (N, K, 3))``
(default :func:`digiteyes.kinematics.keypoints.keypoints`); fingertips are the keypoints whose
names end with ``".tip"``.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import Any

import numpy as np

from digiteyes.camera import Rig
from digiteyes.errors import DatasetError
from digiteyes.io.dataset import GroundTruth
from digiteyes.io.state_log import StateLog
from digiteyes.kinematics import KinematicModel, Kinematics
from digiteyes.kinematics.anatomy import (
    FINGERS,
    finger_of,
    joint_angle_states,
    joint_type_of,
    palm_pose,
)
from digiteyes.kinematics.keypoints import hand_keypoints, keypoints
from digiteyes.kinematics.rotations import quaternion_angle, wrap_angle

KeypointFn = Callable[[KinematicModel, Kinematics], tuple[Sequence[str], np.ndarray]]

#: default fingertip error (mm) above which a frame counts as track loss
DEFAULT_LOSS_THRESHOLD_MM = 20.0
#: digit prefixes of state names, in report order (others follow in model order)
REPORT_ORDER = (*FINGERS, "thumb")


def _grouped(names: Sequence[str], key: Callable[[str], str]) -> dict[str, list[int]]:
    groups: dict[str, list[int]] = {}
    for i, name in enumerate(names):
        groups.setdefault(key(name), []).append(i)
    order = [f for f in REPORT_ORDER if f in groups] + [g for g in groups
                                                       if g not in REPORT_ORDER]
    return {g: groups[g] for g in order}


# --------------------------------------------------------------------------- statistics
def _stats(values: np.ndarray) -> dict[str, Any]:
    """mean, median, max and RMS of the finite entries (None without any) and their count."""
    x = np.asarray(values, dtype=float).ravel()
    x = x[np.isfinite(x)]
    if not len(x):
        return {"mean": None, "median": None, "max": None, "rms": None, "count": 0}
    return {"mean": float(x.mean()), "median": float(np.median(x)), "max": float(x.max()),
            "rms": float(np.sqrt(np.mean(x * x))), "count": len(x)}


def _angle_stats(err_deg: np.ndarray) -> dict[str, Any]:
    """RMS, mean and max of absolute angle errors (degrees) and their count."""
    x = np.abs(np.asarray(err_deg, dtype=float).ravel())
    if not len(x):
        return {"rms": None, "mean_abs": None, "max_abs": None, "count": 0}
    return {"rms": float(np.sqrt(np.mean(x * x))), "mean_abs": float(x.mean()),
            "max_abs": float(x.max()), "count": len(x)}


def _series(x: np.ndarray) -> list[float | None]:
    return [float(v) if np.isfinite(v) else None for v in np.asarray(x, dtype=float)]


def _row_mean(x: np.ndarray, mask: np.ndarray | None = None) -> np.ndarray:
    """Mean over the last axis (only where ``mask``), nan for rows without entries."""
    if mask is None:
        mask = np.ones(x.shape, dtype=bool)
    mask = mask & np.isfinite(x)
    count = mask.sum(axis=-1)
    total = np.where(mask, x, 0.0).sum(axis=-1)
    return np.divide(total, count, out=np.full(total.shape, np.nan), where=count > 0)


# --------------------------------------------------------------------------- evaluation
def _frame_indices(estimated: StateLog, truth: GroundTruth) -> np.ndarray:
    frames = np.asarray(estimated.frames, dtype=int)
    if not len(frames):
        raise DatasetError("the state log holds no frames")
    if (frames < 0).any() or (frames >= len(truth)).any():
        bad = frames[(frames < 0) | (frames >= len(truth))][0]
        raise DatasetError(f"the state log has frame {bad}, beyond the ground truth "
                           f"(frames 0..{len(truth) - 1})")
    if (np.diff(frames) <= 0).any():
        i = int(np.flatnonzero(np.diff(frames) <= 0)[0])
        raise DatasetError(f"state log frames must increase; frame {frames[i + 1]} follows "
                           f"{frames[i]}")
    return frames


def _true_keypoints(truth: GroundTruth, frames: np.ndarray, model: KinematicModel, rig: Rig,
                    keypoint_fn: KeypointFn):
    """True keypoints at ``frames``: names, (T,K,3), (T,C,K,2), (T,C,K) visible.

    Stored keypoints when the truth has them, else computed from the true states (then a
    keypoint counts as visible when it projects into the image in front of the camera;
    occlusion is unknown).
    """
    if truth.keypoint_names:
        return (truth.keypoint_names, truth.keypoints_3d[frames], truth.keypoints_2d[frames],
                truth.visible[frames])
    if truth.states is None:
        raise DatasetError("the ground truth has neither states nor keypoints")
    names, kp3 = hand_keypoints(model, truth.states[frames], keypoint_fn=keypoint_fn)
    kp2 = np.stack([cam.project(kp3) for cam in rig.cameras], axis=1)
    visible = np.stack([cam.in_image(cam.project(kp3)) & (cam.depth(kp3) > 0)
                        for cam in rig.cameras], axis=1)
    return names, kp3, kp2, visible


def evaluate_run(estimated: StateLog, truth: GroundTruth, model: KinematicModel, rig: Rig,
                 keypoint_fn: KeypointFn | None = None, *,
                 loss_threshold_mm: float = DEFAULT_LOSS_THRESHOLD_MM) -> dict[str, Any]:
    """Compare a tracker's state log with ground truth; see docs/evaluation.md.

    Parameters
    ----------
    estimated : the run's state log; its ``frames`` index the ground truth; its
        ``hand_scale`` sizes the estimated hand
        (:func:`~digiteyes.kinematics.keypoints.hand_keypoints`).
    truth : ground truth of the sequence (states and/or keypoints).
    model : the kinematic model of both.
    rig : the cameras (for reprojection errors).
    keypoint_fn : ``(model, kin) -> (names, (N, K, 3))``; default
        :func:`digiteyes.kinematics.keypoints.keypoints`, the one the renderer uses for the truth.
    loss_threshold_mm : a frame whose mean fingertip error exceeds this counts as track
        loss (thesis §4.1: the state error grows without bound once correspondence is lost).

    Returns
    -------
    dict with ``fingertip_error_mm``, ``keypoint_error_mm``, ``joint_angle_error_deg``,
    ``palm``, ``reprojection_error_px``, ``track_life``, ``run`` and ``per_frame``; entries
    that cannot be computed (no tips, no true states, no palm) are None.
    Raises :class:`DatasetError` when the log and the truth do not fit together.
    """
    if keypoint_fn is None:
        keypoint_fn = keypoints
    frames = _frame_indices(estimated, truth)
    est_states = np.asarray(estimated.states, dtype=float)
    if est_states.shape != (len(frames), model.n_q):
        raise DatasetError(f"the state log holds states of shape {est_states.shape}, model "
                           f"{model.name!r} needs ({len(frames)}, {model.n_q})")
    if truth.states is not None and truth.states.shape[1] != model.n_q:
        raise DatasetError(f"the ground truth holds states of size {truth.states.shape[1]}, "
                           f"model {model.name!r} needs {model.n_q}")
    n = len(frames)
    names_t, kp3_t, kp2_t, vis_t = _true_keypoints(truth, frames, model, rig, keypoint_fn)
    names_e, kp3_e_all = hand_keypoints(model, est_states, estimated.hand_scale, keypoint_fn)
    unknown = [k for k in names_t if k not in names_e]
    if unknown:
        raise DatasetError(f"ground-truth keypoints {', '.join(unknown)} are not keypoints of "
                           f"model {model.name!r} (those are {', '.join(names_e)})")
    kp3_e = kp3_e_all[:, [names_e.index(k) for k in names_t]]
    if kp2_t.shape[1] != len(rig):
        raise DatasetError(f"the ground truth has 2D keypoints for {kp2_t.shape[1]} cameras, "
                           f"the rig has {len(rig)}")

    # 3D keypoint and fingertip errors
    kp_err = np.linalg.norm(kp3_e - kp3_t, axis=-1)  # (T, K)
    tips = [i for i, k in enumerate(names_t) if k.endswith(".tip")]
    tip_err = kp_err[:, tips]
    tip_mean = _row_mean(tip_err) if tips else _row_mean(kp_err)

    # track life (thesis §4.1)
    lost = np.asarray(estimated.lost, dtype=bool)
    too_far = np.nan_to_num(tip_mean, nan=0.0) > loss_threshold_mm
    bad = np.flatnonzero(lost | too_far)
    life = int(bad[0]) if len(bad) else n
    reason = None
    if len(bad):
        reason = "flagged lost" if lost[bad[0]] else \
            f"{'fingertip' if tips else 'keypoint'} error > {loss_threshold_mm:g} mm"
    track_life = {"frames": life, "of_frames": n,
                  "lost_at_frame": int(frames[bad[0]]) if len(bad) else None,
                  "reason": reason, "threshold_mm": float(loss_threshold_mm),
                  "measure": "mean fingertip error" if tips else "mean keypoint error"}

    fingertip = None
    if tips:
        fingertip = _stats(tip_err) | {
            "per_tip": {names_t[i]: _stats(kp_err[:, i]) for i in tips},
            "within_track_life": _stats(tip_err[:life]),
        }
    keypoint = None
    if names_t:
        keypoint = _stats(kp_err) | {"per_keypoint": {k: _stats(kp_err[:, i])
                                                      for i, k in enumerate(names_t)}}

    # joint angles
    joint_angles = None
    angle_rms_series = np.full(n, np.nan)
    if truth.states is not None:
        idx = joint_angle_states(model)
        if len(idx):
            err = np.degrees(wrap_angle(est_states[:, idx] - truth.states[frames][:, idx]))
            names = [model.state_names[i] for i in idx]
            angle_rms_series = np.sqrt(np.mean(err * err, axis=1))
            joint_angles = _angle_stats(err) | {
                "per_finger": {g: _angle_stats(err[:, cols])
                               for g, cols in _grouped(names, finger_of).items()},
                "per_joint_type": {g: _angle_stats(err[:, cols])
                                   for g, cols in _grouped(names, joint_type_of).items()},
                "per_state": {name: _angle_stats(err[:, j]) for j, name in enumerate(names)},
            }

    # palm pose
    palm = None
    palm_pos_series = palm_rot_series = np.full(n, np.nan)
    if truth.states is not None:
        pose_e = palm_pose(model, est_states)
        pose_t = palm_pose(model, truth.states[frames])
        if pose_e is not None and pose_t is not None:
            palm_pos_series = np.linalg.norm(pose_e[1] - pose_t[1], axis=1)
            palm_rot_series = np.degrees(quaternion_angle(pose_e[0], pose_t[0]))
            palm = {"source": pose_e[2], "position_error_mm": _stats(palm_pos_series),
                    "orientation_error_deg": _stats(palm_rot_series)}

    # 2D reprojection of the estimated keypoints, visible true keypoints only
    reprojection = None
    reproj_series = np.full(n, np.nan)
    if names_t:
        err2 = np.stack([np.linalg.norm(cam.project(kp3_e) - kp2_t[:, c], axis=-1)
                         for c, cam in enumerate(rig.cameras)], axis=1)  # (T, C, K)
        err2 = np.where(vis_t, err2, np.nan)
        reproj_series = _row_mean(err2.reshape(n, -1))
        reprojection = _stats(err2) | {"per_camera": {cam.name: _stats(err2[:, c])
                                                      for c, cam in enumerate(rig.cameras)}}

    time_s = np.asarray(estimated.time_s, dtype=float)
    run = {"frames": n, "first_frame": int(frames[0]), "last_frame": int(frames[-1]),
           "truth_frames": len(truth), "lost_frames": int(lost.sum()),
           "residual_rms_px": _stats(estimated.residual_rms_px),
           "iterations_mean": float(np.mean(estimated.iterations)),
           "time_s_mean": float(np.mean(time_s)),
           "time_s_total": float(np.sum(time_s))}

    per_frame = {
        "frame": [int(f) for f in frames],
        "lost": [bool(x) for x in lost],
        "fingertip_error_mm": _series(tip_mean) if tips else None,
        "fingertip_error_mm_per_tip": {names_t[i]: _series(kp_err[:, i]) for i in tips},
        "keypoint_error_mm": _series(_row_mean(kp_err)) if names_t else None,
        "joint_angle_error_deg_rms": _series(angle_rms_series),
        "palm_position_error_mm": _series(palm_pos_series),
        "palm_orientation_error_deg": _series(palm_rot_series),
        "reprojection_error_px": _series(reproj_series),
        "residual_rms_px": _series(estimated.residual_rms_px),
    }
    return {"model": model.name, "fingertip_error_mm": fingertip, "keypoint_error_mm": keypoint,
            "joint_angle_error_deg": joint_angles, "palm": palm,
            "reprojection_error_px": reprojection, "track_life": track_life, "run": run,
            "per_frame": per_frame}
