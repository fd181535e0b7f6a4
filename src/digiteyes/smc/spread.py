"""The start's finger spread carried through the configuration space (ours, not Huang's).

The default 7-D space (:func:`~digiteyes.smc.prior.default_configuration_space`) holds
flexion, not a hand's own spread: projected into it, an open hand whose index is spread
10 degrees more than the basis configurations' loses that spread, its fingertips move up
to 17 mm, and the particle trackers start from a hand that is not there
(docs/divide-and-conquer.md, Known limits). :class:`SpreadHeldSpace` keeps, for each of
the four fingers, the part of the start state's abduction that the space cannot express,
and adds it to every hypothesis *in proportion to how open that finger is*: a finger
curls with its spread shrinking (the basis configurations' curled fingers have none), so a
held offset would be wrong on a curled finger, and a finger that opens again gets its
spread back.

Openness of finger ``f`` at joint angles ``theta``: ``1 - (mcp + pip) / (mcp_c + pip_c)``
clipped to [0, 1], with ``mcp_c, pip_c`` its fully curled angles
(:func:`~digiteyes.kinematics.anatomy.digit_joint_angles`). The offset is fitted at the
start: ``(abd_start - abd_projected) / openness_projected`` (none for a finger less than
:data:`MIN_OPENNESS` open). ``to_joints`` adds ``offset x openness`` to each abduction;
``to_coordinates`` removes it first (at the openness of the joints it is given), so the
two are inverse to a fraction of a degree of abduction.
"""

from __future__ import annotations

from dataclasses import dataclass, fields

import numpy as np

from digiteyes.kinematics.anatomy import digit_joint_angles
from digiteyes.smc.configuration import ConfigurationSpace

FINGERS = ("index", "middle", "ring", "little")
MIN_OPENNESS = 0.2
"""A finger less open than this at the start gets no held spread (its spread is noise)."""


@dataclass(frozen=True)
class SpreadHeldSpace(ConfigurationSpace):
    """A :class:`ConfigurationSpace` that adds the start's spread to open fingers.

    offset : (J,) abduction offset at full openness, rad (0 outside the abduction joints).
    abd : (4,) columns of the fingers' abduction joints; flex : (4, 2) of their MCP and PIP.
    curl : (4,) MCP + PIP of each finger fully curled, rad.
    """

    offset: np.ndarray | None = None
    abd: np.ndarray | None = None
    flex: np.ndarray | None = None
    curl: np.ndarray | None = None

    @classmethod
    def of(cls, space: ConfigurationSpace, start_joints: np.ndarray) -> ConfigurationSpace:
        """``space`` holding the spread of ``start_joints`` (J,) that it cannot express;
        ``space`` itself when it lacks a finger's abduction, MCP or PIP joint."""
        base = _plain(space)
        column = {name: j for j, name in enumerate(base.joint_names)}
        names = [f"{f}.{j}" for f in FINGERS for j in ("abd", "mcp", "pip")]
        if any(n not in column for n in names):
            return space
        abd = np.array([column[f"{f}.abd"] for f in FINGERS])
        flex = np.array([[column[f"{f}.mcp"], column[f"{f}.pip"]] for f in FINGERS])
        curl = np.array([sum(digit_joint_angles(f, False)[f"{f}.{j}"] for j in ("mcp", "pip"))
                         for f in FINGERS])
        start = np.asarray(start_joints, dtype=float)
        projected = base.to_joints(base.to_coordinates(start))
        openness = _openness(projected, flex, curl)[0]
        offset = np.zeros(len(base.joint_names))
        offset[abd] = np.where(openness >= MIN_OPENNESS,
                               (start[abd] - projected[abd]) / np.maximum(openness,
                                                                          MIN_OPENNESS), 0.0)
        return cls(**{f.name: getattr(base, f.name) for f in fields(ConfigurationSpace)},
                   offset=offset, abd=abd, flex=flex, curl=curl)

    def to_joints(self, coordinates: np.ndarray) -> np.ndarray:
        """Joint angles (N, J) of PCA coordinates (N, D) (or (D,) -> (J,)), the held spread
        added to open fingers, clipped to the joint limits, rad."""
        joints = np.atleast_2d(super().to_joints(coordinates))
        joints[:, self.abd] += self.offset[self.abd] * _openness(joints, self.flex, self.curl)
        joints = np.clip(joints, self.lower, self.upper)
        return joints if np.ndim(coordinates) > 1 else joints[0]

    def to_coordinates(self, joints: np.ndarray) -> np.ndarray:
        """PCA coordinates of joint-angle vectors, the held spread removed first."""
        plain = np.array(joints, dtype=float, ndmin=2)
        plain[:, self.abd] -= self.offset[self.abd] * _openness(plain, self.flex, self.curl)
        coordinates = super().to_coordinates(plain)
        return coordinates if np.ndim(joints) > 1 else coordinates[0]


def _plain(space: ConfigurationSpace) -> ConfigurationSpace:
    """The plain space under a :class:`SpreadHeldSpace` (``space`` itself otherwise)."""
    if isinstance(space, SpreadHeldSpace):
        return ConfigurationSpace(**{f.name: getattr(space, f.name)
                                     for f in fields(ConfigurationSpace)})
    return space


def _openness(joints: np.ndarray, flex: np.ndarray, curl: np.ndarray) -> np.ndarray:
    """Openness (N, 4) of each finger at joint angles (N, J) (module docstring)."""
    return np.clip(1.0 - np.atleast_2d(joints)[:, flex].sum(axis=-1) / curl, 0.0, 1.0)
