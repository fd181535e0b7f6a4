"""Ground-truth keypoints of a posed model: joint centres, fingertip centres, palm centre."""

from __future__ import annotations

from collections.abc import Callable, Sequence

import numpy as np

from digiteyes.kinematics import KinematicModel, Kinematics, forward_kinematics
from digiteyes.kinematics.scaling import model_unit_states


def keypoint_names(model: KinematicModel) -> tuple[str, ...]:
    """Names of the keypoints of :func:`keypoints`, in order."""
    return tuple(f"{link.name}.base" if link.kind == "link" else link.name
                 for link in _bodies_and_tips(model))


def _bodies_and_tips(model: KinematicModel) -> list:
    """The links that get a keypoint: every body and tip (tracked edges belong to a body)."""
    return [link for link in model.links if link.kind != "edge"]


def keypoints(model: KinematicModel, kin: Kinematics) -> tuple[tuple[str, ...], np.ndarray]:
    """Names and world positions (N, K, 3), mm, of one keypoint per body and tip (every
    link but the tracked ``edge`` ones, in model order).

    A cylinder link gives its base, the joint centre at the start of its axis (name
    ``"<link>.base"``); a tip gives its sphere centre (the tip's name); the palm gives the
    centre of its box (its name, ``"palm"`` for the hand). The leading N is always present,
    also for a single state.
    """
    links = _bodies_and_tips(model)
    T = kin.T_world_shape[:, [link.row for link in links]]  # (N, K, 4, 4)
    local = np.array([link.centre if link.kind == "palm" else (0.0, 0.0, 0.0)
                      for link in links])
    points = np.einsum("nkij,kj->nki", T[..., :3, :3], local) + T[..., :3, 3]
    return keypoint_names(model), points


def hand_keypoints(model: KinematicModel, states: np.ndarray,
                   hand_scale: float | np.ndarray = 1.0,
                   keypoint_fn: Callable[[KinematicModel, Kinematics],
                                         tuple[Sequence[str], np.ndarray]] = keypoints,
                   ) -> tuple[tuple[str, ...], np.ndarray]:
    """Names and world positions (N, K, 3), mm, of the keypoints of a hand ``hand_scale``
    times the model's size (one scale, or one per state (N,)) at ``states`` (N, n_q) or
    (n_q,): ``s * p(q / s)`` (:func:`~digiteyes.kinematics.scaling.model_unit_states`),
    ``p`` the keypoints of ``keypoint_fn`` (default :func:`keypoints`). Scale 1 is the
    model file's hand."""
    states = np.atleast_2d(np.asarray(states, dtype=float))
    scale = np.broadcast_to(np.asarray(hand_scale, dtype=float), (len(states),))
    kin = forward_kinematics(model, model_unit_states(model, states, scale))
    names, points = keypoint_fn(model, kin)
    points = np.asarray(points, dtype=float).reshape(len(states), len(names), 3)
    return tuple(str(n) for n in names), scale[:, None, None] * points
