"""The anatomy helpers that build states: digits opened (extended) in a state."""

import numpy as np

from digiteyes.kinematics.anatomy import digit_joint_angles, open_digits


def test_open_digits_extends_only_the_named_digits(hand):
    rng = np.random.default_rng(3)
    state = hand.neutral()
    joints = [i for i, kind in enumerate(hand.state_kinds) if kind == "angle"]
    state[joints] = rng.uniform(hand.lower[joints], hand.upper[joints])
    opened = open_digits(hand, state, ["index", "thumb"])
    expected = state.copy()
    for joint in ("mcp", "pip", "dip"):  # a finger's extended angles are 0
        expected[hand.state_index(f"index.{joint}")] = 0.0
    for name, angle in digit_joint_angles("thumb", extended=True).items():
        if name in hand.state_names:  # every thumb joint, clipped to the model's limits
            i = hand.state_index(name)
            expected[i] = np.clip(angle, hand.lower[i], hand.upper[i])
    # the index keeps its abduction, the other fingers and the palm are untouched
    np.testing.assert_array_equal(opened, expected)
    np.testing.assert_array_equal(open_digits(hand, state, []), state)
