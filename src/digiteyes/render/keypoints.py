"""Ground-truth keypoints of a posed model: joint centres, fingertip centres, palm centre."""

from __future__ import annotations

import numpy as np

from digiteyes.kinematics import KinematicModel, Kinematics


def keypoint_names(model: KinematicModel) -> tuple[str, ...]:
    """Names of the keypoints of :func:`keypoints`, in order."""
    names = []
    for link in model.links:
        names.append(f"{link.name}.base" if link.kind == "link" else link.name)
    return tuple(names)


def keypoints(model: KinematicModel, kin: Kinematics) -> tuple[tuple[str, ...], np.ndarray]:
    """Names and world positions (N, K, 3), mm, of one keypoint per link: keypoint k
    belongs to ``model.links[k]``.

    A cylinder link gives its base, the joint centre at the start of its axis (name
    ``"<link>.base"``); a tip gives its sphere centre (the tip's name); the palm gives the
    centre of its box (its name, ``"palm"`` for the hand). The leading N is always present,
    also for a single state.
    """
    T = kin.T_world_shape[:, [link.row for link in model.links]]  # (N, K, 4, 4)
    local = np.array([link.centre if link.kind == "palm" else (0.0, 0.0, 0.0)
                      for link in model.links])
    points = np.einsum("nkij,kj->nki", T[..., :3, :3], local) + T[..., :3, 3]
    return keypoint_names(model), points
