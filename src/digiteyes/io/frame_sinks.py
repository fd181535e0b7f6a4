"""Per-frame outputs of a tracking run that follow the frames as they are tracked.

* :class:`KeypointLog`: ``keypoints.csv``, one row per frame with every model keypoint
  (:func:`digiteyes.kinematics.keypoints.keypoints`: joint centres, fingertip centres, the
  palm centre) in each camera: pixel position ``<camera>.<keypoint>.u_px / v_px`` and the
  point in that camera's frame ``<camera>.<keypoint>.x_mm / y_mm / z_mm``.
* :class:`JsonLinesStream`: one JSON object per frame (state, flags, the same keypoints)
  to standard output (``-``) or a TCP socket (``tcp://HOST:PORT``, digiteyes connects to
  a listening app), for other programs to follow a run live.

Both are :class:`digiteyes.pipeline.FrameSink` objects (``write`` per frame, ``close``).
"""

from __future__ import annotations

import csv
import json
import socket
import sys
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Protocol, TextIO

import numpy as np

from digiteyes.camera import Rig
from digiteyes.camera.mirror import unmirror_points
from digiteyes.errors import DatasetError
from digiteyes.filters import OneEuroFilter, OneEuroOptions
from digiteyes.kinematics import KinematicModel
from digiteyes.kinematics.keypoints import hand_keypoints, keypoint_names

KEYPOINTS_FILE = "keypoints.csv"


class TrackResult(Protocol):
    """What the sinks read of a :class:`digiteyes.trackers.TrackResult` (named here so
    that ``io`` stays below the trackers in the import graph)."""

    state: np.ndarray
    lost: bool
    residual_rms_px: float
    hand_scale: float


class CameraKeypoints:
    """The model keypoints of a state (a hand ``hand_scale`` times the model's size,
    :func:`~digiteyes.kinematics.keypoints.hand_keypoints`) in every camera of ``rig``,
    in the real images and camera frames (:meth:`~digiteyes.camera.Rig.real_pixels`; a
    mirrored rig's points reflected back, :mod:`digiteyes.camera.mirror`).

    One per run, shared by its sinks: the keypoint log and the stream ask for the same
    frame's keypoints one after the other, so the last call's arrays are returned again
    for the same state and scale (read them, do not write).
    """

    def __init__(self, model: KinematicModel, rig: Rig) -> None:
        self.model = model
        self.rig = rig
        self._last: tuple[tuple[bytes, float], tuple] | None = None

    def __call__(self, q: np.ndarray, hand_scale: float = 1.0
                 ) -> tuple[tuple[str, ...], np.ndarray, np.ndarray]:
        """Names, pixels (n_cameras, K, 2) and camera-frame points (n_cameras, K, 3), mm,
        of the keypoints of state ``q``."""
        q = np.asarray(q, dtype=float)
        key = (q.tobytes(), float(hand_scale))
        if self._last is None or self._last[0] != key:
            self._last = key, self._compute(q, hand_scale)
        return self._last[1]

    def _compute(self, q: np.ndarray, hand_scale: float
                 ) -> tuple[tuple[str, ...], np.ndarray, np.ndarray]:
        names, world = hand_keypoints(self.model, q, hand_scale)
        world = world[0]
        rig = self.rig
        uv = np.stack([rig.real_pixels(cam.project(world), c) for c, cam in enumerate(rig)])
        xyz = np.stack([cam.to_camera(world) for cam in rig])
        if rig.mirrored:
            xyz = unmirror_points(xyz)
        return names, uv, xyz


class KeypointLog:
    """Write ``keypoints.csv`` (flushed per row, like ``states.csv``)."""

    def __init__(self, path: str | Path, keypoints: CameraKeypoints) -> None:
        self.path = Path(path)
        self.keypoints = keypoints
        self.rig = keypoints.rig
        try:
            self._handle = open(self.path, "w", newline="", encoding="utf-8")
        except OSError as exc:
            raise DatasetError(f"{self.path}: cannot create ({exc.strerror or exc})") from None
        self._writer = csv.writer(self._handle)
        self._writer.writerow(["frame", *keypoint_columns(keypoints.model, keypoints.rig)])

    def write(self, index: int, images: Sequence[np.ndarray], result: TrackResult,
              reinitialised: bool) -> None:
        """Append the keypoints of ``result.state``."""
        _, uv, xyz = self.keypoints(result.state, result.hand_scale)
        row = [str(index)]
        for c in range(len(self.rig)):
            for k in range(uv.shape[1]):
                row += [f"{uv[c, k, 0]:.2f}", f"{uv[c, k, 1]:.2f}",
                        *(f"{v:.2f}" for v in xyz[c, k])]
        self._writer.writerow(row)
        self._handle.flush()

    def close(self) -> None:
        self._handle.close()


def keypoint_columns(model: KinematicModel, rig: Rig) -> list[str]:
    """The named columns of ``keypoints.csv`` after ``frame``, camera by camera."""
    return [f"{cam.name}.{name}.{axis}" for cam in rig for name in keypoint_names(model)
            for axis in ("u_px", "v_px", "x_mm", "y_mm", "z_mm")]


def frame_message(keypoints: CameraKeypoints, index: int, result: TrackResult,
                  reinitialised: bool) -> dict:
    """One frame as a JSON-ready object: ``frame``, ``time`` (Unix s), ``lost``,
    ``reinitialised``, ``residual_rms_px``, ``state`` (by name; mm, rad), ``hand_scale``
    (the hand's size relative to the model file) and
    ``keypoints[camera][keypoint] = {"uv_px": [u, v], "xyz_mm": [x, y, z]}``."""
    rms = float(result.residual_rms_px)
    return {
        "frame": int(index),
        "time": time.time(),
        "lost": bool(result.lost),
        "reinitialised": bool(reinitialised),
        "residual_rms_px": rms if np.isfinite(rms) else None,
        "state": state_by_name(keypoints.model, result.state),
        "hand_scale": float(result.hand_scale),
        "keypoints": keypoints_by_camera(keypoints, result.state, result.hand_scale),
    }


def state_by_name(model: KinematicModel, state: np.ndarray) -> dict[str, float]:
    """A state (n_q,) as ``{state name: value}`` (mm, rad)."""
    return {n: float(v) for n, v in zip(model.state_names, state, strict=True)}


def keypoints_by_camera(keypoints: CameraKeypoints, state: np.ndarray,
                        hand_scale: float = 1.0) -> dict:
    """``{camera: {keypoint: {"uv_px": [u, v], "xyz_mm": [x, y, z]}}}`` of a state (n_q,)
    of a hand ``hand_scale`` times the model's size: the projection (px) and the point in
    the camera's frame (mm), rounded to 0.01."""
    names, uv, xyz = keypoints(state, hand_scale)
    return {cam.name: {n: {"uv_px": [round(float(u), 2) for u in uv[c, k]],
                           "xyz_mm": [round(float(v), 2) for v in xyz[c, k]]}
                       for k, n in enumerate(names)}
            for c, cam in enumerate(keypoints.rig)}


def parse_stream_target(target: str) -> tuple[str, int] | None:
    """``"-"`` gives None (standard output); ``"tcp://HOST:PORT"`` gives ``(HOST, PORT)``.
    Anything else raises :class:`DatasetError`."""
    if target == "-":
        return None
    host, sep, port = target.removeprefix("tcp://").rpartition(":")
    if not target.startswith("tcp://") or not sep or not host or not port.isdigit():
        raise DatasetError(f"--stream: expected '-' or tcp://HOST:PORT, got {target!r}")
    return host, int(port)


class JsonLinesStream:
    """Send :func:`frame_message` per frame as one line of JSON to ``target`` (``-`` or
    ``tcp://HOST:PORT``). A reader that goes away ends the stream quietly (the run goes
    on); a socket that cannot be reached raises :class:`DatasetError` at once.

    With ``smooth`` (One Euro settings) each line also carries ``state_smoothed`` and
    ``keypoints_smoothed``: the state filtered online at ``fps`` frames/s
    (:class:`~digiteyes.filters.OneEuroFilter`, restarting on the frame after a lost
    one, as ``states-smoothed.csv``), for live use.
    """

    def __init__(self, target: str, keypoints: CameraKeypoints, out: TextIO | None = None,
                 smooth: OneEuroOptions | None = None, fps: float = 10.0) -> None:
        self.keypoints = keypoints
        self.model = keypoints.model
        self._socket = None
        self._filter = None if smooth is None else OneEuroFilter(self.model, fps, smooth)
        address = parse_stream_target(target)
        if address is None:
            self._out = out or sys.stdout
        else:
            try:
                self._socket = socket.create_connection(address, timeout=5.0)
            except OSError as exc:
                raise DatasetError(f"--stream {target}: cannot connect ({exc})") from None
            self._out = self._socket.makefile("w", encoding="utf-8", newline="\n")
        self.n_sent = 0

    def write(self, index: int, images: Sequence[np.ndarray], result: TrackResult,
              reinitialised: bool) -> None:
        if self._out is None:
            return
        message = frame_message(self.keypoints, index, result, reinitialised)
        if self._filter is not None:
            smoothed = self._filter.follow(result.state, result.lost)
            message["state_smoothed"] = state_by_name(self.model, smoothed)
            message["keypoints_smoothed"] = keypoints_by_camera(self.keypoints, smoothed,
                                                                result.hand_scale)
        try:
            self._out.write(json.dumps(message) + "\n")
            self._out.flush()
            self.n_sent += 1
        except (OSError, ValueError):
            self._out = None

    def close(self) -> None:
        if self._socket is not None:
            try:
                if self._out is not None:
                    self._out.close()
            except OSError:
                pass
            self._socket.close()
            self._socket = None
        self._out = None
