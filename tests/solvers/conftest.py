"""Synthetic least-squares problems for the solver tests: fit a hand state to noise-free
projections of its own joint, tip and palm-corner points (no images needed)."""

from __future__ import annotations

import numpy as np
import pytest

from digiteyes.camera import Camera
from digiteyes.kinematics import (
    KinematicModel,
    forward_kinematics,
    integrate,
    load_model,
    point_jacobian,
)
from digiteyes.trackers.parameterisation import StateParameterisation


def model_points(model: KinematicModel) -> tuple[np.ndarray, np.ndarray]:
    """Rows and shape-frame points: both ends of every cylinder, every tip centre and the
    eight palm-box corners (mm)."""
    axis_rows, axis_points = model.axis_and_tip_points()
    rows, points = list(axis_rows), list(axis_points)
    for link in model.links:
        if link.kind == "palm":
            half = 0.5 * np.asarray(link.size)
            for sign in np.array(np.meshgrid([-1, 1], [-1, 1], [-1, 1])).reshape(3, -1).T:
                rows.append(link.row)
                points.append(np.asarray(link.centre) + sign * half)
    return np.array(rows), np.array(points, dtype=float)


class PointAlignmentProblem:
    """Residuals ``project(p(q)) - target`` (px) over all cameras, stacked (thesis Sec. 2.5.5).

    ``form`` picks the step layout (tangent n_v or the thesis's quaternion n_q); ``clip``
    clips joint limits after each step. ``evaluations`` counts residual calls.
    """

    def __init__(self, model, cameras, q_true, form="tangent", clip=False, rows=None,
                 points=None):
        self.model = model
        self.cameras = cameras
        self.param = StateParameterisation(model, form, clip)
        self.n_v = self.param.n_v
        default_rows, default_points = model_points(model)
        self.rows = default_rows if rows is None else rows
        self.points = default_points if points is None else points
        p = forward_kinematics(model, q_true).points(self.rows, self.points)
        self.targets = [cam.project(p) for cam in cameras]
        self.evaluations = 0

    def residuals(self, x, jacobian):
        self.evaluations += 1
        kin = forward_kinematics(self.model, x)
        p, Jp = point_jacobian(kin, self.rows, self.points, form=self.param.form)
        rs, Js = [], []
        for cam, target in zip(self.cameras, self.targets, strict=True):
            w, dw = cam.project_with_jacobian(p)
            rs.append((w - target).ravel())
            if jacobian:
                Js.append(np.einsum("pij,pjk->pik", dw, Jp).reshape(-1, self.n_v))
        return np.concatenate(rs), (np.concatenate(Js) if jacobian else None)

    def retract(self, x, dv):
        return self.param.retract(x, dv)

    def project(self, x):
        return self.param.project(x)


@pytest.fixture(scope="session")
def hand() -> KinematicModel:
    return load_model("hand")


@pytest.fixture(scope="session")
def cameras() -> list[Camera]:
    """Two cameras 450 mm below the palm's back, 300 mm apart, verging on the hand."""
    target = (0.0, 60.0, 0.0)
    return [
        Camera.look_at("left", (-150.0, 60.0, -420.0), target, up=(0, 1, 0), width=320,
                       height=240, focal_px=400),
        Camera.look_at("right", (150.0, 80.0, -420.0), target, up=(0, 1, 0), width=320,
                       height=240, focal_px=400),
    ]


@pytest.fixture(scope="session")
def q_true(hand) -> np.ndarray:
    """A mildly flexed hand, slightly rotated and shifted."""
    q = hand.neutral()
    angle = 0.2
    q[0:4] = (np.cos(angle / 2), 0.0, np.sin(angle / 2) * 0.6, np.sin(angle / 2) * 0.8)
    q[4:7] = (5.0, -3.0, 8.0)
    for finger in ("index", "middle", "ring", "little"):
        q[hand.state_index(f"{finger}.mcp")] = 0.3
        q[hand.state_index(f"{finger}.pip")] = 0.4
        q[hand.state_index(f"{finger}.dip")] = 0.2
    q[hand.state_index("thumb.mp")] = 0.2
    return q


def _perturb(model, q, rng, rotation=0.05, translation=5.0, joint=0.1):
    dv = np.zeros(model.n_v)
    dv[0:3] = rng.normal(scale=rotation, size=3)
    dv[3:6] = rng.normal(scale=translation, size=3)
    dv[6:] = rng.uniform(-joint, joint, size=model.n_v - 6)
    return integrate(model, q, dv)


@pytest.fixture(scope="session")
def perturb():
    """``perturb(model, q, rng, rotation=0.05, translation=5.0, joint=0.1)``: ``q`` moved
    by a random tangent step of those sizes (rad, mm, rad)."""
    return _perturb


@pytest.fixture(scope="session")
def point_problem():
    """The :class:`PointAlignmentProblem` class (test modules cannot import conftest)."""
    return PointAlignmentProblem
