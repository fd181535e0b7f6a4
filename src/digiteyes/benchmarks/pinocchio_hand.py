"""An independent pinocchio model of Rehg's hand (thesis Appendix A), the reference for
tests and benchmarks.

Why a second model: ``tests/kinematics/test_pinocchio.py`` compares digiteyes' forward
kinematics and point Jacobians with pinocchio, and ``digiteyes bench kinematics`` times
both. For the comparison to check anything, the reference must not go through digiteyes'
model-file parser, tree builder or DH code. This module therefore

* transcribes thesis Table A.1 itself, as the Python table :data:`APPENDIX_A` (frame
  numbers, constant DH parts, the state added to theta, ``next`` pointers), with the one
  fix the shipped ``hand.dh`` also makes: the thumb rows 34 and 35 carry q26 and q27
  (the printed table repeats q25; the thumb has five states q23..q27);
* composes each DH transform from its four elementary factors
  ``Rot_z(theta) Trans_z(d) Trans_x(a) Rot_x(alpha)`` (thesis eq. 2.2) by matrix products;
* builds a pinocchio tree: a free-flyer joint for the palm, one revolute ``RZ`` joint per
  row whose theta holds a state, and two operational frames per table row: ``frame{r}``
  (row r's own DH frame) and ``shape{r}`` (frame r followed by ``Rot_z(theta_r)``, thesis
  eq. 2.4). Optional extra frames sit at given points of shape frames.

Both the test and the benchmark import it, so the transcription lives in one place.
pinocchio (pip name ``pin``) is a test-only dependency: importing this module imports it.

Conventions: millimetres, radians; our state (28 numbers) is palm quaternion (w, x, y, z),
palm translation, then the 21 joint angles; pinocchio's free-flyer configuration is
(x, y, z, qx, qy, qz, qw), see :meth:`PinocchioHand.configuration`.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import pinocchio as pin

N_STATES = 28
"""Size of the hand's state vector (thesis Sec. 2.2.2)."""


@dataclass(frozen=True)
class DHRow:
    """One row of thesis Table A.1.

    ``theta`` is the constant part of the joint angle (radians); ``state`` is the index of
    the state added to it (a revolute joint) or None; ``d`` and ``a`` are millimetres,
    ``alpha`` radians; ``next`` lists the frames this row's transform leads to.
    """

    frame: int
    theta: float
    state: int | None
    d: float
    a: float
    alpha: float
    next: tuple[int, ...]


_PI = math.pi


def _finger(first: int, first_state: int, a0: float, d1: float,
            lengths: tuple[float, float, float]) -> tuple[DHRow, ...]:
    """The seven rows of a finger: two constant rows to the MCP anchor, abduction, three
    flexion links, the tip (the pattern of Table A.1 rows 1-7)."""
    f, s = first, first_state
    return (
        DHRow(f, _PI / 2, None, 0.0, a0, -_PI / 2, (f + 1,)),
        DHRow(f + 1, 0.0, None, d1, 0.0, _PI / 2, (f + 2,)),
        DHRow(f + 2, 0.0, s, 0.0, 0.0, _PI / 2, (f + 3,)),
        DHRow(f + 3, 0.0, s + 1, 0.0, lengths[0], 0.0, (f + 4,)),
        DHRow(f + 4, 0.0, s + 2, 0.0, lengths[1], 0.0, (f + 5,)),
        DHRow(f + 5, 0.0, s + 3, 0.0, lengths[2], 0.0, (f + 6,)),
        DHRow(f + 6, 0.0, None, 0.0, 0.0, 0.0, ()),
    )


APPENDIX_A: tuple[DHRow, ...] = (
    DHRow(0, 0.0, None, 0.0, 0.0, 0.0, (1, 8, 15, 22, 29)),  # palm; its pose is q0..q6
    *_finger(1, 7, 38.0, -31.0, (45.0, 26.0, 24.0)),  # index (finger 1)
    *_finger(8, 11, 37.0, -9.0, (56.0, 27.0, 22.0)),  # middle (finger 2)
    *_finger(15, 15, 33.0, 6.0, (53.0, 25.0, 20.0)),  # ring (finger 3)
    *_finger(22, 19, 30.0, 26.0, (38.0, 19.0, 17.0)),  # little (finger 4)
    DHRow(29, -_PI / 2, None, 15.0, 43.0, -_PI / 2, (30,)),  # thumb
    DHRow(30, -_PI, None, 38.0, 0.0, 0.0, (31,)),
    DHRow(31, 0.0, 23, 0.0, 0.0, _PI / 2, (32,)),
    DHRow(32, 0.0, 24, 0.0, 46.0, -_PI / 2, (33,)),
    DHRow(33, 0.0, 25, 0.0, 0.0, _PI / 2, (34,)),
    DHRow(34, 0.0, 26, 0.0, 34.0, 0.0, (35,)),  # printed as q25, see module docstring
    DHRow(35, 0.0, 27, 0.0, 25.0, 0.0, (36,)),
    DHRow(36, 0.0, None, 0.0, 0.0, 0.0, ()),
)
"""Thesis Table A.1 (27 DOF right hand, 37 frames), transcribed by hand."""


def _rot_z(theta: float) -> np.ndarray:
    c, s = math.cos(theta), math.sin(theta)
    out = np.eye(4)
    out[:2, :2] = [[c, -s], [s, c]]
    return out


def _rot_x(alpha: float) -> np.ndarray:
    c, s = math.cos(alpha), math.sin(alpha)
    out = np.eye(4)
    out[1:3, 1:3] = [[c, -s], [s, c]]
    return out


def _trans(x: float, y: float, z: float) -> np.ndarray:
    out = np.eye(4)
    out[:3, 3] = (x, y, z)
    return out


def _se3(T: np.ndarray) -> pin.SE3:
    return pin.SE3(T[:3, :3].copy(), T[:3, 3].copy())


@dataclass(frozen=True)
class PinocchioHand:
    """The pinocchio hand and the index maps between its layout and ours.

    Attributes
    ----------
    model : the pinocchio model (free-flyer palm + 21 ``RZ`` joints); ``model.nq == 28``,
        ``model.nv == 27``.
    frame_ids : pinocchio frame id of DH frame r, for r = 0..36.
    shape_ids : pinocchio frame id of shape frame r (frame r then ``Rot_z(theta_r)``).
    point_ids : pinocchio frame ids of the extra point frames, in the order requested.
    joint_q_index : (28,) for our state s >= 7, the index of its angle in pinocchio's
        configuration vector; -1 for the palm states 0..6.
    joint_v_index : (28,) for our state s >= 7, its column in pinocchio's (6, nv) Jacobians;
        -1 for the palm states (columns 0..2 are the palm's LOCAL linear velocity, 3..5
        its LOCAL angular velocity).
    """

    model: pin.Model
    frame_ids: tuple[int, ...]
    shape_ids: tuple[int, ...]
    point_ids: tuple[int, ...]
    joint_q_index: np.ndarray
    joint_v_index: np.ndarray

    def configuration(self, q: np.ndarray) -> np.ndarray:
        """Pinocchio configuration(s) of our state(s) ``q`` (..., 28).

        Free flyer (x, y, z, qx, qy, qz, qw) from our translation q4..q6 and quaternion
        (w, x, y, z) q0..q3, normalised (our forward kinematics normalises too); then the
        joint angles in pinocchio's joint order.
        """
        q = np.asarray(q, dtype=float)
        out = np.empty((*q.shape[:-1], self.model.nq))
        quat = q[..., 0:4] / np.linalg.norm(q[..., 0:4], axis=-1, keepdims=True)
        out[..., 0:3] = q[..., 4:7]
        out[..., 3:6] = quat[..., 1:4]
        out[..., 6] = quat[..., 0]
        joints = np.arange(7, N_STATES)
        out[..., self.joint_q_index[joints]] = q[..., joints]
        return out


def build_pinocchio_hand(
    point_rows: Sequence[int] = (),
    point_offsets: np.ndarray | None = None,
) -> PinocchioHand:
    """Build the Appendix A hand in pinocchio from :data:`APPENDIX_A`.

    Parameters
    ----------
    point_rows : (P,) table rows; an extra operational frame ``point{i}`` is added at each
        point, rigidly attached to the shape frame of its row (axes parallel to it).
    point_offsets : (P, 3) the points in those shape frames, mm.

    Returns
    -------
    PinocchioHand
        The model and the index maps; create ``model.createData()`` to evaluate it.
    """
    rows = {row.frame: row for row in APPENDIX_A}
    offsets = np.zeros((0, 3)) if point_offsets is None else np.asarray(point_offsets, float)
    if offsets.shape != (len(point_rows), 3):
        raise ValueError(
            f"point_offsets must have shape ({len(point_rows)}, 3), got {offsets.shape}"
        )
    model = pin.Model()
    model.name = "rehg_hand_appendix_a"
    palm = model.addJoint(0, pin.JointModelFreeFlyer(), pin.SE3.Identity(), "palm")
    joint_frame = {palm: model.addJointFrame(palm)}
    frame_ids = [-1] * len(rows)
    shape_ids = [-1] * len(rows)
    shape_carrier: dict[int, tuple[int, np.ndarray]] = {}
    joint_q = np.full(N_STATES, -1)
    joint_v = np.full(N_STATES, -1)
    # Depth-first over the `next` pointers; each entry: (row, carrying joint, T_joint_frame).
    stack: list[tuple[int, int, np.ndarray]] = [(0, palm, np.eye(4))]
    while stack:
        r, joint, T_joint_frame = stack.pop()
        row = rows[r]
        frame_ids[r] = model.addFrame(pin.Frame(
            f"frame{r}", joint, joint_frame[joint], _se3(T_joint_frame), pin.FrameType.OP_FRAME,
        ))
        if row.state is not None:
            joint = model.addJoint(joint, pin.JointModelRZ(), _se3(T_joint_frame), f"q{row.state}")
            joint_frame[joint] = model.addJointFrame(joint)
            joint_q[row.state] = model.joints[joint].idx_q
            joint_v[row.state] = model.joints[joint].idx_v
            T_joint_frame = np.eye(4)
        T_joint_shape = T_joint_frame @ _rot_z(row.theta)
        shape_ids[r] = model.addFrame(pin.Frame(
            f"shape{r}", joint, joint_frame[joint], _se3(T_joint_shape), pin.FrameType.OP_FRAME,
        ))
        shape_carrier[r] = (joint, T_joint_shape)
        T_joint_next = T_joint_shape @ _trans(0.0, 0.0, row.d) @ _trans(row.a, 0.0, 0.0)
        T_joint_next = T_joint_next @ _rot_x(row.alpha)
        stack.extend((child, joint, T_joint_next) for child in reversed(row.next))
    point_ids = []
    for i, (r, offset) in enumerate(zip(point_rows, offsets, strict=True)):
        joint, T_joint_shape = shape_carrier[int(r)]
        T_joint_point = T_joint_shape @ _trans(*offset)
        point_ids.append(model.addFrame(pin.Frame(
            f"point{i}", joint, joint_frame[joint], _se3(T_joint_point), pin.FrameType.OP_FRAME,
        )))
    return PinocchioHand(model, tuple(frame_ids), tuple(shape_ids), tuple(point_ids),
                         joint_q, joint_v)
