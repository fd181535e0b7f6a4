"""Exports of a track for other tools: BVH and glTF 2.0 animations, CSV and Parquet tables.

:func:`export_track` is what ``digiteyes export`` calls; one module per format.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from digiteyes.errors import DigitEyesError
from digiteyes.io.export.bvh import write_bvh
from digiteyes.io.export.gltf import write_gltf
from digiteyes.io.export.skeleton import Skeleton, build_skeleton, skeleton_motion
from digiteyes.io.export.table import track_table, write_table_csv, write_table_parquet
from digiteyes.kinematics import KinematicModel

FORMATS = {"bvh": "track.bvh", "gltf": "track.glb", "csv": "track.csv",
           "parquet": "track.parquet"}
"""Export format -> file name written in the output folder."""


def export_track(model: KinematicModel, frames: np.ndarray, states: np.ndarray,
                 lost: np.ndarray, fps: float, out_dir: str | Path, fmt: str,
                 mirrored: bool = False) -> Path:
    """Write one export of a track (states (T, n_q) at ``fps``) into ``out_dir``; return
    the file written (named by :data:`FORMATS`). ``mirrored``: the states are a left
    hand's, tracked as the mirror image's right hand; the export shows the left hand."""
    if fmt not in FORMATS:
        raise DigitEyesError(f"unknown export format {fmt!r}; choose from {', '.join(FORMATS)}")
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    path = out / FORMATS[fmt]
    if fmt == "bvh":
        return write_bvh(path, model, states, fps, mirrored)
    if fmt == "gltf":
        return write_gltf(path, model, states, fps, mirrored)
    columns = track_table(model, frames, states, lost, mirrored)
    if fmt == "csv":
        return write_table_csv(path, columns)
    return write_table_parquet(path, columns)


__all__ = ["FORMATS", "Skeleton", "build_skeleton", "export_track", "skeleton_motion",
           "track_table", "write_bvh", "write_gltf", "write_table_csv", "write_table_parquet"]
