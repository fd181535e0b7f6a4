"""The thesis conditioning matrix in both step layouts."""

from __future__ import annotations

import numpy as np
import pytest

from digiteyes.kinematics import load_model
from digiteyes.solvers import hand_conditioning


def test_tangent_layout(hand):
    S = hand_conditioning(hand)
    assert S.shape == (hand.n_v,) == (27,)
    names = hand.tangent_names
    for name, weight in zip(names, S, strict=True):
        expected = {"rx": 1.0, "ry": 1.0, "rz": 1.0, "x": 10.0, "y": 10.0, "z": 10.0}.get(
            name.split(".")[1] if name.startswith("palm.") else "", 1000.0)
        assert weight == expected, name


def test_quaternion_layout_and_custom_weights(hand):
    S = hand_conditioning(hand, quaternion=2.0, translation=3.0, joint=4.0, form="quaternion")
    assert S.shape == (hand.n_q,)
    np.testing.assert_array_equal(S[:4], 2.0)
    np.testing.assert_array_equal(S[4:7], 3.0)
    np.testing.assert_array_equal(S[7:], 4.0)


def test_other_models_follow_their_state_kinds():
    model = load_model("mouse-hand")
    S = hand_conditioning(model, form="quaternion")
    kinds = np.array(model.state_kinds)
    assert np.all(S[kinds == "angle"] == 1000.0)
    assert np.all(S[np.isin(kinds, ["trans", "length"])] == 10.0)
    assert hand_conditioning(model).shape == (model.n_v,)


@pytest.mark.parametrize(("kwargs", "match"), [
    ({"joint": -1.0}, "joint"), ({"translation": np.nan}, "translation"),
    ({"form": "euler"}, "form"),
])
def test_bad_arguments(hand, kwargs, match):
    with pytest.raises(ValueError, match=match):
        hand_conditioning(hand, **kwargs)
