"""Flat tables of a track: states, joint angles and 3D keypoints per frame (CSV, Parquet).

One row per frame; columns ``frame``, ``lost``, the model's state names (mm, radians,
quaternion w, x, y, z), ``<anatomical joint name>_deg`` (degrees,
:mod:`digiteyes.kinematics.joint_angles`), then ``<keypoint>_x_mm``, ``_y_mm``, ``_z_mm``
(world mm, :func:`~digiteyes.kinematics.keypoints.keypoints`). Parquet needs pyarrow (the
``export`` extra).
"""

from __future__ import annotations

import csv
from pathlib import Path

import numpy as np

from digiteyes.camera.mirror import unmirror_points
from digiteyes.errors import DatasetError, DigitEyesError
from digiteyes.kinematics import KinematicModel, forward_kinematics
from digiteyes.kinematics.joint_angles import joint_angles_deg
from digiteyes.kinematics.keypoints import keypoints


def track_table(model: KinematicModel, frames: np.ndarray, states: np.ndarray,
                lost: np.ndarray | None = None, mirrored: bool = False
                ) -> dict[str, np.ndarray]:
    """Named columns (each (T,)) of the table described in the module docstring; with
    ``mirrored`` (a left hand) the keypoints are the real hand's (x -> -x) and the state
    columns stay the mirror image's."""
    states = np.atleast_2d(np.asarray(states, dtype=float))
    columns: dict[str, np.ndarray] = {
        "frame": np.asarray(frames, dtype=np.int64),
        "lost": np.zeros(len(states), dtype=np.int64) if lost is None
        else np.asarray(lost, dtype=np.int64),
    }
    for i, name in enumerate(model.state_names):
        columns[name] = states[:, i]
    names, degrees = joint_angles_deg(model, states)
    for k, name in enumerate(names):
        columns[f"{name}_deg"] = degrees[:, k]
    names, points = keypoints(model, forward_kinematics(model, states))
    if mirrored:
        points = unmirror_points(points)
    for k, name in enumerate(names):
        for a, axis in enumerate("xyz"):
            columns[f"{name}_{axis}_mm"] = points[:, k, a]
    return columns


def write_table_csv(path: str | Path, columns: dict[str, np.ndarray]) -> Path:
    """Write named columns as CSV (integers as integers, floats at full precision)."""
    path = Path(path)
    arrays = list(columns.values())
    try:
        with open(path, "w", newline="", encoding="utf-8") as handle:
            writer = csv.writer(handle)
            writer.writerow(list(columns))
            for t in range(len(arrays[0])):
                writer.writerow([int(a[t]) if a.dtype.kind == "i" else repr(float(a[t]))
                                 for a in arrays])
    except OSError as exc:
        raise DatasetError(f"{path}: cannot write CSV ({exc.strerror or exc})") from None
    return path


def write_table_parquet(path: str | Path, columns: dict[str, np.ndarray]) -> Path:
    """Write named columns as Parquet. Raises :class:`DigitEyesError` when pyarrow is
    not installed (``pip install digiteyes[export]``)."""
    try:
        import pyarrow as pa
        import pyarrow.parquet as pq
    except ImportError:
        raise DigitEyesError("Parquet export needs pyarrow: pip install 'digiteyes[export]'"
                             ) from None
    path = Path(path)
    try:
        pq.write_table(pa.table(columns), path)
    except OSError as exc:
        raise DatasetError(f"{path}: cannot write Parquet ({exc})") from None
    return path
