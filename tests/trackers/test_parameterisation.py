"""Step forms: the tangent retraction and the thesis's normalised-quaternion form."""

from __future__ import annotations

import numpy as np
import pytest

from digiteyes.camera import Camera
from digiteyes.kinematics import forward_kinematics, integrate, load_model, point_jacobian
from digiteyes.trackers.parameterisation import StateParameterisation

HAND = load_model("hand")


def random_state(rng):
    q = HAND.neutral()
    quat = rng.normal(size=4)
    q[0:4] = quat / np.linalg.norm(quat)
    q[4:7] = rng.uniform(-50, 50, size=3)
    q[7:] = rng.uniform(HAND.lower[7:], HAND.upper[7:])
    return q


def test_tangent_form_is_integrate():
    rng = np.random.default_rng(0)
    q, dv = random_state(rng), rng.normal(scale=0.1, size=HAND.n_v)
    param = StateParameterisation(HAND, "tangent")
    assert param.n_v == 27
    np.testing.assert_array_equal(param.retract(q, dv), integrate(HAND, q, dv))


def test_quaternion_form_adds_and_renormalises():
    rng = np.random.default_rng(1)
    q, dq = random_state(rng), rng.normal(scale=0.1, size=HAND.n_q)
    param = StateParameterisation(HAND, "quaternion")
    assert param.n_v == 28
    before = q.copy()
    out = param.retract(q, dq)
    np.testing.assert_array_equal(q, before)
    np.testing.assert_allclose(out[4:], q[4:] + dq[4:])
    np.testing.assert_allclose(out[:4], (q[:4] + dq[:4]) / np.linalg.norm(q[:4] + dq[:4]))
    np.testing.assert_allclose(param.retract(q, np.zeros(28)), q, rtol=0, atol=1e-15)


@pytest.mark.parametrize("form", ["tangent", "quaternion"])
def test_point_jacobian_matches_the_retraction(form):
    """Finite differences stepped through ``retract`` reproduce the projected point
    Jacobian of that form (the pairing the solvers rely on)."""
    rng = np.random.default_rng(2)
    q = random_state(rng)
    param = StateParameterisation(HAND, form, clip=False)
    cam = Camera.look_at("c", (30.0, 60.0, -400.0), (0.0, 50.0, 0.0), up=(0, 1, 0))
    rows = np.array([link.row for link in HAND.links])
    p_shape = rng.normal(scale=10.0, size=(len(rows), 3))
    _, Jp = point_jacobian(forward_kinematics(HAND, q), rows, p_shape, form=form)
    _, dw = cam.project_with_jacobian(forward_kinematics(HAND, q).points(rows, p_shape))
    J = np.einsum("pij,pjk->pik", dw, Jp)
    h = 1e-6
    for i in range(param.n_v):
        step = np.zeros(param.n_v)
        step[i] = h
        plus = cam.project(forward_kinematics(HAND, param.retract(q, step)).points(rows, p_shape))
        minus = cam.project(forward_kinematics(HAND, param.retract(q, -step)).points(rows,
                                                                                     p_shape))
        np.testing.assert_allclose((plus - minus) / (2 * h), J[..., i], atol=2e-4, rtol=1e-5)


def test_project_clips_only_when_asked():
    q = HAND.neutral()
    q[HAND.state_index("index.pip")] = 5.0
    assert StateParameterisation(HAND, clip=True).project(q)[9] == HAND.upper[9]
    assert StateParameterisation(HAND, clip=False).project(q)[9] == 5.0


def test_bad_form():
    with pytest.raises(ValueError, match="form"):
        StateParameterisation(HAND, "euler")
