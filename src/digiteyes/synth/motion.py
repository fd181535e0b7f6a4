"""Motion-script helpers for the synthetic scenarios: smooth keyframe paths, palm rotations
and the image speed of the keypoints.

Everything here is deterministic: random keyframes come from a ``numpy.random.Generator``
passed in by the caller. Times are in frames unless a name says seconds; angles in
radians; positions in world millimetres; image positions in pixels.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from digiteyes.camera import Rig
from digiteyes.kinematics import KinematicModel, forward_kinematics
from digiteyes.kinematics.keypoints import keypoints
from digiteyes.kinematics.rotations import (
    quaternion_from_matrix,
    quaternion_from_rotvec,
    quaternion_multiply,
)


def min_jerk(s: np.ndarray) -> np.ndarray:
    """The minimum-jerk profile ``10 s^3 - 15 s^4 + 6 s^5`` on [0, 1] (clipped outside).

    It goes from 0 to 1 with zero velocity and acceleration at both ends (Flash & Hogan's
    model of point-to-point human arm motion); its peak slope is 1.875 at ``s = 0.5``.
    """
    s = np.clip(np.asarray(s, dtype=float), 0.0, 1.0)
    return s**3 * (10.0 + s * (-15.0 + 6.0 * s))


def keyframe_path(key_times: Sequence[float], key_values: np.ndarray,
                  times: np.ndarray) -> np.ndarray:
    """Minimum-jerk interpolation through keyframes.

    Parameters
    ----------
    key_times : (K,) strictly increasing keyframe times (any unit, the same as ``times``).
    key_values : (K, D) or (K,) values at the keyframes.
    times : (T,) sample times.

    Returns
    -------
    (T, D) or (T,) values: each stretch between two keyframes follows :func:`min_jerk`,
    so the path stops (zero velocity) at every keyframe, the way a hand moves from pose to
    pose. Before the first and after the last keyframe the value is held.
    """
    key_times = np.asarray(key_times, dtype=float)
    values = np.asarray(key_values, dtype=float)
    if key_times.ndim != 1 or len(key_times) != len(values) or len(key_times) == 0:
        raise ValueError(f"need K keyframe times and K values, got {key_times.shape} and "
                         f"{values.shape}")
    if np.any(np.diff(key_times) <= 0):
        raise ValueError("keyframe times must increase strictly")
    times = np.asarray(times, dtype=float)
    flat = values.reshape(len(values), -1)
    if len(key_times) == 1:
        out = np.broadcast_to(flat[0], (len(times), flat.shape[1])).copy()
        return out.reshape((len(times), *values.shape[1:]))
    seg = np.clip(np.searchsorted(key_times, times, side="right") - 1, 0, len(key_times) - 2)
    t0, t1 = key_times[seg], key_times[seg + 1]
    s = min_jerk((times - t0) / (t1 - t0))[:, None]
    out = flat[seg] + s * (flat[seg + 1] - flat[seg])
    return out.reshape((len(times), *values.shape[1:]))


def random_key_times(rng: np.random.Generator, n_frames: int, min_gap: float,
                     max_gap: float) -> np.ndarray:
    """Keyframe times from 0 past ``n_frames - 1`` with gaps drawn uniformly in
    [min_gap, max_gap] frames."""
    times = [0.0]
    while times[-1] < n_frames - 1:
        times.append(times[-1] + rng.uniform(min_gap, max_gap))
    return np.array(times)


def random_keyframe_path(rng: np.random.Generator, n_frames: int, low: np.ndarray,
                         high: np.ndarray, min_gap: float, max_gap: float,
                         start: np.ndarray | None = None) -> np.ndarray:
    """A smooth random path (n_frames, D): minimum-jerk moves between keyframes drawn
    uniformly in the box [low, high], every ``min_gap``..``max_gap`` frames.

    ``start`` (D,) fixes the first keyframe (default: the box centre).
    """
    low = np.atleast_1d(np.asarray(low, dtype=float))
    high = np.atleast_1d(np.asarray(high, dtype=float))
    key_times = random_key_times(rng, n_frames, min_gap, max_gap)
    keys = rng.uniform(low, high, size=(len(key_times), len(low)))
    keys[0] = (low + high) / 2 if start is None else start
    return keyframe_path(key_times, keys, np.arange(n_frames))


def palm_quaternions(R_world_rest: np.ndarray, rotvecs: np.ndarray) -> np.ndarray:
    """Base quaternions (T, 4), (w, x, y, z), of ``exp([r]x) R_world_rest`` for world-frame
    rotation vectors ``rotvecs`` (T, 3), radians: the rest orientation turned about world
    axes through the palm origin (the convention of ``integrate``)."""
    rest = quaternion_from_matrix(np.asarray(R_world_rest, dtype=float))
    quat = quaternion_multiply(quaternion_from_rotvec(rotvecs), rest)
    quat /= np.linalg.norm(quat, axis=-1, keepdims=True)
    return quat * np.where(quat[..., :1] < 0, -1.0, 1.0)


def image_speed(model: KinematicModel, states: np.ndarray, rig: Rig) -> np.ndarray:
    """Largest image displacement per frame of any keypoint in any camera, (T,) px/frame.

    Entry t is the displacement from frame t-1 to frame t (entry 0 is 0). The keypoints
    are the renderer's ground-truth keypoints (:func:`digiteyes.kinematics.keypoints.keypoints`:
    joint centres, tip centres, palm centre); this is the number to compare with a
    tracker's search window (thesis Sec. 4.3.2: track loss when the features leave it).
    """
    points = keypoints(model, forward_kinematics(model, np.atleast_2d(states)))[1]
    speed = np.zeros(len(points))
    for cam in rig:
        w = cam.project(points)
        step = np.linalg.norm(np.diff(w, axis=0), axis=-1).max(axis=-1)
        speed[1:] = np.maximum(speed[1:], step)
    return speed
