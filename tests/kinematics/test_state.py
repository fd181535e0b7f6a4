"""States: named access, validation, the retraction (integrate/difference), files."""

from __future__ import annotations

import json
import math
import re

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from digiteyes.errors import StateError
from digiteyes.kinematics import (
    State,
    clip_to_limits,
    difference,
    held_at_limits,
    integrate,
    load_model,
    read_states_csv,
    validate_state,
    write_states_csv,
)
from digiteyes.kinematics.rotations import matrix_from_quaternion, quaternion_from_rotvec

HAND = load_model("hand")  # module level: hypothesis tests cannot take function fixtures

finite = st.floats(-1e3, 1e3, allow_nan=False, allow_infinity=False)


@st.composite
def unit_states(draw) -> np.ndarray:
    """Hand states with a unit quaternion of either sign of w (|w| >= 0.1 before scaling)."""
    w = draw(st.floats(0.1, 1.0)) * draw(st.sampled_from([-1.0, 1.0]))
    xyz = draw(arrays(float, 3, elements=st.floats(-1.0, 1.0)))
    rest = draw(arrays(float, 24, elements=finite))
    quat = np.r_[w, xyz]
    return np.r_[quat / np.linalg.norm(quat), rest]


small_steps = arrays(float, 27, elements=st.floats(-0.5, 0.5))


# ------------------------------------------------------------------ named access
def test_named_access():
    state = State(HAND)
    assert state["index.pip"] == 0.0
    assert state["palm.qw"] == 1.0
    state["index.pip"] = 0.7
    assert state["q9"] == 0.7
    assert state.q[9] == 0.7
    assert list(state)[:2] == ["palm.qw", "palm.qx"]
    assert len(list(state)) == 28
    assert state.to_dict()["index.pip"] == 0.7


def test_state_copies_its_input():
    q = HAND.neutral()
    state = State(HAND, q)
    state["thumb.ip"] = 0.5
    assert q[27] == 0.0


@pytest.mark.parametrize("name", ["index.pipp", "q28", "thumb", ""])
def test_unknown_names_are_rejected(name):
    state = State(HAND)
    with pytest.raises(StateError, match=f"no state {re.escape(repr(name))}"):
        state[name]
    with pytest.raises(StateError, match="no state"):
        state[name] = 1.0


def test_setting_non_finite_value_is_rejected():
    with pytest.raises(StateError, match=r"'index\.mcp' must be finite"):
        State(HAND)["index.mcp"] = math.nan


# ------------------------------------------------------------------ validation
def bad(index: int, value: float) -> np.ndarray:
    q = HAND.neutral()
    q[index] = value
    return q


@pytest.mark.parametrize(
    ("q", "match"),
    [
        (np.zeros(27), r"needs states of size 28.*got shape \(27,\)"),
        (np.zeros(29), r"needs states of size 28.*got shape \(29,\)"),
        (bad(12, math.nan), r"q12 \(middle\.mcp\) is not finite"),
        (bad(5, -math.inf), r"q5 \(palm\.y\) is not finite"),
        (bad(0, 1.1), r"q0\.\.q3 must have unit norm, got norm 1\.1\b"),
        (bad(0, 0.0), r"q0\.\.q3 is zero"),
    ],
)
def test_invalid_states_are_rejected(q, match):
    with pytest.raises(StateError, match=match):
        validate_state(HAND, q)
    with pytest.raises(StateError, match=match):
        State(HAND, q)


def test_state_holds_one_state():
    with pytest.raises(StateError, match=r"one state of size 28, got shape \(2, 28\)"):
        State(HAND, np.tile(HAND.neutral(), (2, 1)))


def test_validate_normalises_on_request():
    q = bad(0, 3.0)
    q[1] = 4.0
    out = validate_state(HAND, q, normalize=True)
    np.testing.assert_allclose(out[:4], [0.6, 0.8, 0.0, 0.0])
    assert q[0] == 3.0  # the input is not modified
    np.testing.assert_allclose(validate_state(HAND, np.tile(q, (3, 1)), normalize=True)[:, :4],
                               np.tile([0.6, 0.8, 0.0, 0.0], (3, 1)))


def test_clip_to_limits():
    q = HAND.neutral()
    q[9] = 3.0  # index PIP above 110 degrees
    q[8] = -1.0  # index MCP below -30 degrees
    out = clip_to_limits(HAND, q)
    assert out[9] == pytest.approx(math.radians(110))
    assert out[8] == pytest.approx(math.radians(-30))
    np.testing.assert_array_equal(out[:7], q[:7])


def test_held_at_limits_names_the_joints_the_cost_pushes_beyond_a_limit():
    """A joint at its lower limit is held when the descent direction (minus the
    gradient) points further down, not when it points back inside; likewise at the upper
    limit; joints inside their limits and the palm's pose (no limits) are never held."""
    q = clip_to_limits(HAND, HAND.neutral())
    pip, mcp, dip = (HAND.state_index(f"index.{j}") for j in ("pip", "mcp", "dip"))
    q[pip], q[mcp] = HAND.upper[pip], HAND.lower[mcp]
    q[dip] = 0.5 * (HAND.lower[dip] + HAND.upper[dip])
    column = HAND.q_to_v
    gradient = np.zeros(HAND.n_v)
    gradient[column[pip]], gradient[column[mcp]], gradient[column[dip]] = -1.0, 1.0, 1.0
    gradient[:6] = 1.0  # the palm's rotation and translation
    held = held_at_limits(HAND, q, gradient)
    assert held[column[pip]] and held[column[mcp]]
    assert held.sum() == 2
    assert not held_at_limits(HAND, q, -gradient).any()  # back inside: free


# ------------------------------------------------------------------ retraction
@settings(max_examples=60, deadline=None)
@given(unit_states())
def test_integrate_zero_is_identity(q):
    np.testing.assert_allclose(integrate(HAND, q, np.zeros(27)), q, rtol=0, atol=1e-12)


@settings(max_examples=60, deadline=None)
@given(unit_states(), small_steps)
def test_difference_inverts_integrate(q, dv):
    q1 = integrate(HAND, q, dv)
    np.testing.assert_allclose(np.linalg.norm(q1[:4]), 1.0, atol=1e-14)
    np.testing.assert_allclose(difference(HAND, q, q1), dv, rtol=0, atol=1e-9)


@settings(max_examples=30, deadline=None)
@given(unit_states(), unit_states())
def test_integrate_inverts_difference(q0, q1):
    back = integrate(HAND, q0, difference(HAND, q0, q1))
    # Same rotation (quaternions equal up to sign), same everything else.
    np.testing.assert_allclose(abs(np.dot(back[:4], q1[:4])), 1.0, atol=1e-12)
    np.testing.assert_allclose(back[4:], q1[4:], rtol=0, atol=1e-9)


def test_rotation_step_is_applied_in_the_world_frame():
    q = HAND.neutral()
    q[0:4] = quaternion_from_rotvec([0.4, -0.2, 0.9])
    q[4:7] = 5.0, 6.0, 7.0
    dv = np.zeros(27)
    dv[0:3] = 0.0, 0.3, 0.0
    dv[3:6] = 1.0, 2.0, 3.0
    dv[6] = 0.25  # index abduction: tangent index 6 is state q7
    out = integrate(HAND, q, dv)
    turn = matrix_from_quaternion(quaternion_from_rotvec([0.0, 0.3, 0.0]))
    np.testing.assert_allclose(matrix_from_quaternion(out[0:4]),
                               turn @ matrix_from_quaternion(q[0:4]), atol=1e-14)
    np.testing.assert_allclose(out[4:7], [6.0, 8.0, 10.0])
    assert out[7] == 0.25
    assert HAND.tangent_names[:7] == ("palm.rx", "palm.ry", "palm.rz", "palm.x", "palm.y",
                                      "palm.z", "index.abd")


def test_integrate_and_difference_batch():
    rng = np.random.default_rng(50)
    q = np.tile(HAND.neutral(), (4, 1))
    dv = rng.uniform(-0.3, 0.3, size=(4, 27))
    q1 = integrate(HAND, q, dv)
    assert q1.shape == (4, 28)
    for n in range(4):
        np.testing.assert_allclose(q1[n], integrate(HAND, q[n], dv[n]), atol=1e-15)
    np.testing.assert_allclose(difference(HAND, q, q1), dv, atol=1e-12)
    # One state, many steps.
    assert integrate(HAND, HAND.neutral(), dv).shape == (4, 28)


# ------------------------------------------------------------------ files
def random_unit_state(rng: np.random.Generator) -> np.ndarray:
    q = rng.uniform(-1.0, 1.0, size=28)
    q[0:4] /= np.linalg.norm(q[0:4])
    return q


def test_json_round_trip(tmp_path):
    q = random_unit_state(np.random.default_rng(51))
    path = tmp_path / "state.json"
    State(HAND, q).save_json(path)
    payload = json.loads(path.read_text())
    assert payload["model"] == "hand"
    assert payload["state"]["index.pip"] == q[9]
    np.testing.assert_array_equal(State.load_json(HAND, path).q, q)


def test_json_bare_mapping(tmp_path):
    path = tmp_path / "bare.json"
    path.write_text(json.dumps(State(HAND).to_dict()))
    np.testing.assert_array_equal(State.load_json(HAND, path).q, HAND.neutral())


@pytest.mark.parametrize(
    ("content", "match"),
    [
        ('{"model": "two-finger", "state": {}}', "for model 'two-finger', not 'hand'"),
        ('{"state": {"palm.qw": 1.0}}', "missing palm.qx"),
        ("[1, 2]", "expected a JSON object"),
        ("{not json", "not a readable JSON state file"),
        ('{"state": 3}', "'state' must be an object"),
    ],
)
def test_json_errors(tmp_path, content, match):
    path = tmp_path / "bad.json"
    path.write_text(content)
    with pytest.raises(StateError, match=match):
        State.load_json(HAND, path)


def test_json_unknown_and_bad_values(tmp_path):
    values = State(HAND).to_dict()
    path = tmp_path / "extra.json"
    path.write_text(json.dumps({**values, "index.pipp": 0.1}))
    with pytest.raises(StateError, match=r"unknown index\.pipp"):
        State.load_json(HAND, path)
    path.write_text(json.dumps({**values, "palm.qw": 2.0}))
    with pytest.raises(StateError, match="unit norm"):
        State.load_json(HAND, path)
    path.write_text(json.dumps({**values, "palm.x": "left"}))
    with pytest.raises(StateError, match="must be numbers"):
        State.load_json(HAND, path)
    with pytest.raises(StateError, match="no such state file"):
        State.load_json(HAND, tmp_path / "missing.json")


def test_csv_round_trip(tmp_path):
    rng = np.random.default_rng(52)
    states = np.array([random_unit_state(rng) for _ in range(3)])
    path = tmp_path / "states.csv"
    write_states_csv(HAND, path, states, extra={"frame": [0, 1, 2]})
    header = path.read_text().splitlines()[0].split(",")
    assert header[:3] == ["frame", "palm.qw", "palm.qx"]
    back, extra = read_states_csv(HAND, path)
    np.testing.assert_array_equal(back, states)
    assert extra == {"frame": ["0", "1", "2"]}


def test_csv_errors(tmp_path):
    path = tmp_path / "states.csv"
    write_states_csv(HAND, path, [HAND.neutral()])
    lines = path.read_text().splitlines()
    path.write_text(lines[0].replace("index.pip", "index.pipp") + "\n" + lines[1] + "\n")
    with pytest.raises(StateError, match=r"columns for model 'hand' missing: index\.pip$"):
        read_states_csv(HAND, path)
    path.write_text(lines[0] + "\n" + lines[1] + ",7\n")
    with pytest.raises(StateError, match=r"states\.csv:2: expected 28 cells, got 29"):
        read_states_csv(HAND, path)
    path.write_text(lines[0] + "\n" + lines[1].replace("1.0", "2.0", 1) + "\n")
    with pytest.raises(StateError, match="unit norm"):
        read_states_csv(HAND, path)
    path.write_text("")
    with pytest.raises(StateError, match="empty CSV"):
        read_states_csv(HAND, path)


def test_resampled_motion_keeps_the_path_and_stretches_the_time():
    """Played 4x slower, every 4th state is an original one and the others lie between
    their neighbours (a joint angle moving linearly stays linear); played 2x faster, every
    other state; the base rotation is interpolated along the great circle (unit
    quaternions, halfway at half the angle)."""
    from digiteyes.kinematics import difference, integrate, load_model, resample_states

    model = load_model("hand")
    states = np.repeat(model.neutral()[None], 5, axis=0)
    states[:, 9] = np.linspace(0.0, 0.4, 5)
    slow = resample_states(model, states, 0.25)
    assert len(slow) == 17
    np.testing.assert_allclose(slow[::4], states, atol=1e-12)
    np.testing.assert_allclose(slow[:, 9], np.linspace(0.0, 0.4, 17), atol=1e-12)
    np.testing.assert_allclose(resample_states(model, states, 2.0), states[::2], atol=1e-12)
    turn = np.zeros(model.n_v)
    turn[model.q_to_v[model.base_state]] = 0.6
    turned = np.stack([states[0], integrate(model, states[0], turn)])
    halfway = resample_states(model, turned, 0.5)[1]
    np.testing.assert_allclose(np.linalg.norm(halfway[:4]), 1.0, atol=1e-12)
    np.testing.assert_allclose(difference(model, turned[0], halfway), turn / 2, atol=1e-9)
    with pytest.raises(StateError, match="speed"):
        resample_states(model, states, 0.0)
