"""The hand's anatomy in one place: digit names, the states that move the palm, the joint
angles, and the basis configurations of Huang, Wu & Lin (Sec. 2).

Names follow the shipped hand models (docs/models.md): a state ``index.pip`` belongs to
the finger ``index``; the thumb's joints are ``thumb.cmc_flex`` ... ``thumb.ip``.
"""

from __future__ import annotations

from collections.abc import Sequence
from itertools import product

import numpy as np

from digiteyes.kinematics.forward import forward_kinematics
from digiteyes.kinematics.model import KinematicModel
from digiteyes.kinematics.rotations import quaternion_from_matrix

_DEG = np.pi / 180.0

FINGERS = ("index", "middle", "ring", "little")
"""The four fingers, radial to ulnar (the thumb is a digit, not a finger)."""
DIGITS = ("thumb", *FINGERS)
"""All five digits in the order of the basis-configuration names (thumb first)."""
THUMB_JOINTS = ("thumb.cmc_flex", "thumb.cmc_abd", "thumb.mp_abd", "thumb.mp", "thumb.ip")
"""The thumb's five joint states (thesis Sec. 2.2.2)."""
SPREAD_DEG = {"index": -20.0, "middle": -5.0, "ring": 8.0, "little": 22.0}
"""Abduction (degrees) of fingers held apart, so that neighbours do not touch (positive
turns a finger towards the little-finger side, docs/models.md)."""

EXTENDED_FINGER_DEG = {"abd": None, "mcp": 0.0, "pip": 0.0, "dip": 0.0}
CURLED_FINGER_DEG = {"abd": 0.0, "mcp": 80.0, "pip": 95.0, "dip": 60.0}
EXTENDED_THUMB_DEG = dict(zip(THUMB_JOINTS, (40.0, 10.0, 0.0, 0.0, 0.0), strict=True))
CURLED_THUMB_DEG = dict(zip(THUMB_JOINTS, (0.0, 50.0, 0.0, -20.0, -20.0), strict=True))
"""Joint angles (degrees) of extended and curled digits in the basis configurations; an
extended finger keeps the spread abduction :data:`SPREAD_DEG`, a curled one lies beside
its neighbours (abduction 0)."""


def finger_of(state_name: str) -> str:
    """Digit (or part) of a state: the prefix before the first dot (``index.pip`` -> index)."""
    return state_name.split(".", 1)[0]


def joint_type_of(state_name: str) -> str:
    """Joint type of a state: the suffix for fingers (``abd``, ``mcp``, ``pip``, ``dip``);
    thumb joints keep their full name (``thumb.cmc_abd``), as each is its own type."""
    prefix, dot, suffix = state_name.partition(".")
    if not dot:
        return state_name
    return state_name if prefix == "thumb" else suffix


def palm_pose(model: KinematicModel, states: np.ndarray
              ) -> tuple[np.ndarray, np.ndarray, str] | None:
    """Palm orientation (T, 4) quaternions (w, x, y, z) and position (T, 3) mm, world frame.

    With a pose base (7 states) they are those states ("pose states"); otherwise they are
    the pose of the palm link's shape frame from forward kinematics ("palm frame"), which
    for a palm on prismatic joints moves exactly by those joints. None when the model has
    neither a pose base nor a palm link.
    """
    states = np.atleast_2d(np.asarray(states, dtype=float))
    if model.base_state is not None:
        k = model.base_state
        quat = states[:, k:k + 4]
        return quat / np.linalg.norm(quat, axis=1, keepdims=True), states[:, k + 4:k + 7], \
            "pose states"
    palm = [link for link in model.links if link.kind == "palm"]
    if not palm:
        return None
    T = forward_kinematics(model, states).T_world_shape[:, palm[0].row]
    return quaternion_from_matrix(T[:, :3, :3]), T[:, :3, 3].copy(), "palm frame"


def palm_states(model: KinematicModel) -> np.ndarray:
    """Indices of the states that move the palm (the pose base or the joints under it)."""
    palm = [link for link in model.links if link.kind == "palm"]
    if palm:
        return np.flatnonzero(model.shape_moved_by[palm[0].row])
    if model.base_state is not None:
        return np.arange(model.base_state, model.base_state + 7)
    return np.zeros(0, dtype=int)


def joint_angle_states(model: KinematicModel) -> np.ndarray:
    """Indices of the joint angles: states of kind ``angle`` that do not move the palm."""
    moving_palm = set(palm_states(model).tolist())
    return np.array([i for i, kind in enumerate(model.state_kinds)
                     if kind == "angle" and i not in moving_palm], dtype=int)


def basis_configurations() -> list[str]:
    """The 28 basis configurations (Huang, Wu & Lin Sec. 2): every digit fully extended
    (``E``) or fully curled (``C``), digits in the order of :data:`DIGITS`. Of the 32
    combinations we drop the four with the ring finger extended while both of its
    neighbours are curled, which a hand cannot hold (the paper does not list its 28)."""
    names = []
    for combo in product("EC", repeat=5):
        if combo[3] == "E" and combo[2] == "C" and combo[4] == "C":
            continue
        names.append("".join(combo))
    return names


def digit_joint_angles(digit: str, extended: bool) -> dict[str, float]:
    """Joint angles (rad) of one digit fully extended or fully curled, by state name; an
    extended finger keeps its spread abduction :data:`SPREAD_DEG`."""
    if digit == "thumb":
        table = EXTENDED_THUMB_DEG if extended else CURLED_THUMB_DEG
        return {name: value * _DEG for name, value in table.items()}
    values = dict(EXTENDED_FINGER_DEG if extended else CURLED_FINGER_DEG)
    if values["abd"] is None:
        values["abd"] = SPREAD_DEG[digit]
    return {f"{digit}.{joint}": value * _DEG for joint, value in values.items()}


def open_digits(model: KinematicModel, state: np.ndarray, digits: Sequence[str]
                ) -> np.ndarray:
    """``state`` (n_q,) with each of ``digits`` fully extended (:func:`with_digits`)."""
    return with_digits(model, state, digits, extended=True)


def with_digits(model: KinematicModel, state: np.ndarray, digits: Sequence[str],
                extended: bool) -> np.ndarray:
    """``state`` (n_q,) with each of ``digits`` fully extended or fully curled: its flexion
    joints (and all of the thumb's) at the angles of :func:`digit_joint_angles`, clipped
    to the model's limits; a finger keeps its abduction. Joints the model lacks are
    skipped."""
    out = np.array(state, dtype=float)
    names = set(model.state_names)
    for digit in digits:
        for name, angle in digit_joint_angles(digit, extended=extended).items():
            if name in names and joint_type_of(name) != "abd":
                i = model.state_index(name)
                out[i] = np.clip(angle, model.lower[i], model.upper[i])
    return out


def basis_joint_angles(model: KinematicModel, name: str) -> np.ndarray:
    """The joint part of a basis configuration as a full state (n_q,) with a zero base
    (joints the model lacks, such as the cardboard hand's ``thumb.mp_abd``, are skipped)."""
    q = np.zeros(model.n_q)
    names = set(model.state_names)
    for digit, letter in zip(DIGITS, name, strict=True):
        for joint, value in digit_joint_angles(digit, letter == "E").items():
            if joint in names:
                q[model.state_index(joint)] = value
    return q
