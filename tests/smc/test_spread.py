"""The start's spread carried through the configuration space (smc.spread)."""

from __future__ import annotations

import numpy as np
import pytest

from digiteyes.kinematics import load_model
from digiteyes.kinematics.anatomy import digit_joint_angles
from digiteyes.smc.prior import default_configuration_space
from digiteyes.smc.spread import FINGERS, SpreadHeldSpace


@pytest.fixture(scope="module")
def space():
    return default_configuration_space(load_model("cardboard-hand"))


def open_hand(space, extra_spread_deg):
    """An open hand (every finger extended) with each finger's abduction changed by
    ``extra_spread_deg`` (4,), degrees."""
    joints = space.to_joints(space.basis[space.basis_names.index("EEEEE")])
    for f, extra in zip(FINGERS, extra_spread_deg, strict=True):
        joints[space.joint_names.index(f"{f}.abd")] += np.radians(extra)
    return joints


def test_an_open_hand_keeps_its_spread_that_the_space_cannot_express(space):
    """Spread changed by 4, 3, 3 and 2 degrees (inside the joint limits): the plain space
    loses most of it, the held space gives the start back to a tenth of a degree."""
    start = open_hand(space, (-4.0, -3.0, 3.0, 2.0))
    plain = space.to_joints(space.to_coordinates(start))
    held = SpreadHeldSpace.of(space, start)
    abd = [space.joint_names.index(f"{f}.abd") for f in FINGERS]
    assert np.abs(plain[abd] - start[abd]).max() > np.radians(1.5)
    back = held.to_joints(held.to_coordinates(start))
    np.testing.assert_allclose(back[abd], start[abd], atol=np.radians(0.1))
    # the other joints stay where the plain space puts them, within half a degree
    others = np.setdiff1d(np.arange(len(start)), abd)
    np.testing.assert_allclose(back[others], plain[others], atol=np.radians(0.5))


def test_the_held_spread_fades_as_a_finger_curls(space):
    start = open_hand(space, (-4.0, 0.0, 0.0, 0.0))
    held = SpreadHeldSpace.of(space, start)
    index_abd = space.joint_names.index("index.abd")
    curled = space.basis[space.basis_names.index("ECCCC")]
    extended = space.basis[space.basis_names.index("EEEEE")]
    gap = held.to_joints(np.stack([extended, curled]))[:, index_abd] - space.to_joints(
        np.stack([extended, curled]))[:, index_abd]
    openness = 1.0 - sum(space.to_joints(extended)[space.joint_names.index(f"index.{j}")]
                         for j in ("mcp", "pip")) / sum(
        digit_joint_angles("index", False)[f"index.{j}"] for j in ("mcp", "pip"))
    assert held.offset[index_abd] < np.radians(-1.0)
    assert gap[0] == pytest.approx(held.offset[index_abd] * min(max(openness, 0.0), 1.0),
                                   abs=1e-9)
    assert abs(gap[1]) < 0.2 * abs(gap[0])


def test_a_start_inside_the_space_holds_nothing(space):
    start = space.to_joints(space.basis[3])
    held = SpreadHeldSpace.of(space, start)
    np.testing.assert_allclose(held.offset, 0.0, atol=1e-9)
    X = np.random.default_rng(1).normal(0.0, 0.3, (5, space.n_dims))
    np.testing.assert_allclose(held.to_joints(X), space.to_joints(X), atol=1e-9)
    assert SpreadHeldSpace.of(held, start).offset is not None  # refits from the plain space


def test_the_tracker_option_starts_from_the_spread_it_was_given(space):
    """``hold_start_spread``: after ``reset`` the particles stand for the start's spread
    (within a tenth of a degree); without it the start loses it."""
    from digiteyes.camera import Camera
    from digiteyes.trackers.divide_conquer import DivideConquerOptions, DivideConquerTracker

    model = load_model("cardboard-hand")
    camera = Camera.look_at("cam", np.array([0.0, -400.0, 100.0]), np.array([0.0, 0.0, 80.0]))
    q = model.neutral()
    idx = space.joint_indices(model)
    q[idx] = open_hand(space, (-4.0, -3.0, 3.0, 2.0))
    abd = [model.state_index(f"{f}.abd") for f in FINGERS]
    spread = []
    for hold in (False, True):
        tracker = DivideConquerTracker(model, [camera],
                                       options=DivideConquerOptions(hold_start_spread=hold))
        tracker.reset(q)
        start = tracker.space.states(model, q, tracker.particles[:1])[0]
        spread.append(np.abs(start[abd] - q[abd]).max())
        assert isinstance(tracker.space, SpreadHeldSpace) == hold
    assert spread[0] > np.radians(1.5) and spread[1] < np.radians(0.1)
