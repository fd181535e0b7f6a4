"""The model files shipped in ``digiteyes/models``: sizes, limits, geometry and signs.

Sizes and signs are those documented in each file's header and in docs/models.md; expected
positions are worked out by hand from thesis Appendix A (anchors, link lengths), never by
calling the code under test.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from digiteyes.kinematics import KinematicModel, forward_kinematics, load_model
from digiteyes.models import shipped_models

# name: (n_q, n_v, frames, rigid bodies, tips, joint states (angle or length), base pose)
SIZES = {
    "hand": (28, 27, 43, 16, 5, 21, True),
    "mouse-hand": (8, 8, 26, 10, 3, 8, False),
    "two-finger": (9, 9, 19, 7, 2, 9, False),
    "cardboard-hand": (27, 26, 37, 16, 5, 20, True),
}
FINGERS = ("index", "middle", "ring", "little")
# MCP anchors in the palm frame (thesis Appendix A; thumb: base of the metacarpal).
ANCHORS = {
    "index": (31.0, 38.0, 0.0),
    "middle": (9.0, 37.0, 0.0),
    "ring": (-6.0, 33.0, 0.0),
    "little": (-26.0, 30.0, 0.0),
}
THUMB_ANCHOR = {"hand": (38.0, -43.0, 15.0), "mouse-hand": (38.0, -43.0, 0.0),
                "cardboard-hand": (38.0, -43.0, 15.0)}
REST_HEIGHT = 7.5  # mouse-hand: palm frame and finger axes above the table, mm
STEP = 0.2  # rad, a small joint step from the zero state


@pytest.fixture(scope="module", params=sorted(SIZES))
def model(request: pytest.FixtureRequest) -> KinematicModel:
    return load_model(request.param)


def palm_pose(model: KinematicModel, q: np.ndarray) -> np.ndarray:
    """T_world_palm (4x4) for state q."""
    return forward_kinematics(model, q).T_world_shape[0, model.link("palm").row]


def origin_in_palm(model: KinematicModel, q: np.ndarray, row: int) -> np.ndarray:
    """Origin of frame ``row`` in palm coordinates (mm)."""
    kin = forward_kinematics(model, q)
    T_world_palm = kin.T_world_shape[0, model.link("palm").row]
    return np.linalg.solve(T_world_palm, kin.T_world_frame[0, row, :, 3])[:3]


def tip_shift_in_palm(model: KinematicModel, digit: str, state: str, step: float = STEP,
                      q: np.ndarray | None = None) -> np.ndarray:
    """How far the tip of ``digit`` moves, in palm axes, when ``state`` grows by ``step``."""
    q0 = model.neutral() if q is None else q
    q1 = q0.copy()
    q1[model.state_index(state)] += step
    tips = []
    for q_ in (q0, q1):
        kin = forward_kinematics(model, q_)
        T_world_palm = kin.T_world_shape[0, model.link("palm").row]
        tip = kin.T_world_shape[0, model.link(f"{digit}.tip").row, :3, 3]
        tips.append(T_world_palm[:3, :3].T @ tip)
    return tips[1] - tips[0]


def digits(model: KinematicModel) -> list[str]:
    return [link.name.split(".")[0] for link in model.links if link.kind == "tip"]


def flexion_states(model: KinematicModel) -> list[tuple[str, str]]:
    """(finger, state) for every MCP/PIP/DIP state of the four fingers in the model."""
    return [(name.split(".")[0], name) for name in model.state_names
            if name.split(".")[0] in FINGERS and name.split(".")[1] in ("mcp", "pip", "dip")]


# ------------------------------------------------------------------------ loading, sizes
def test_all_four_models_ship() -> None:
    assert set(SIZES) <= set(shipped_models())


def test_sizes(model: KinematicModel) -> None:
    n_q, n_v, frames, bodies, tips, joints, pose = SIZES[model.name]
    assert (model.n_q, model.n_v, model.n_frames) == (n_q, n_v, frames)
    assert sum(link.kind in ("link", "palm") for link in model.links) == bodies
    assert sum(link.kind == "tip" for link in model.links) == tips
    assert sum(kind in ("angle", "length") for kind in model.state_kinds) == joints
    assert (model.base_state is not None) == pose
    assert model.link("palm").kind == "palm"


def test_state_layouts() -> None:
    two = load_model("two-finger")
    assert two.state_kinds == ("length",) * 3 + ("angle",) * 6
    mouse = load_model("mouse-hand")
    assert mouse.state_names == ("palm.x", "palm.y", "palm.rot", "index.mcp", "index.pip",
                                 "index.dip", "little.abd", "thumb.abd")


def test_describe_lists_every_state_and_link(model: KinematicModel) -> None:
    text = model.describe()
    assert text.startswith(f"model {model.name}")
    for name in model.state_names:
        assert name in text
    for link in model.links:
        assert link.name in text


def test_neutral_state_is_zero_and_within_limits(model: KinematicModel) -> None:
    q = model.neutral()
    assert np.all(model.lower <= q) and np.all(q <= model.upper)
    expected = np.zeros(model.n_q)
    if model.base_state is not None:
        expected[model.base_state] = 1.0
    np.testing.assert_array_equal(q, expected)


def test_every_joint_has_finite_limits(model: KinematicModel) -> None:
    for i, kind in enumerate(model.state_kinds):
        if kind in ("angle", "length"):
            assert np.isfinite(model.lower[i]) and np.isfinite(model.upper[i]), i
            assert model.lower[i] < model.upper[i]
        if kind == "angle":
            assert -math.pi <= model.lower[i] and model.upper[i] <= math.pi


def test_links_reuse_appendix_a_dimensions(model: KinematicModel) -> None:
    """Every finger or thumb link named as in hand.dh has its length and radius."""
    hand = load_model("hand")
    hand_links = {link.name: link for link in hand.links}
    for link in model.links:
        if link.kind != "palm":
            ref = hand_links[link.name]
            assert (link.kind, link.length, link.radius) == (ref.kind, ref.length, ref.radius)


# ---------------------------------------------------------------------- palm-frame geometry
def test_finger_anchors_in_the_palm_frame(model: KinematicModel) -> None:
    for finger in digits(model):
        if finger == "thumb":
            row = model.link("thumb.metacarpal").row
            expected = THUMB_ANCHOR[model.name]
        else:
            row = model.link(f"{finger}.proximal").row
            expected = ANCHORS[finger]
        np.testing.assert_allclose(origin_in_palm(model, model.neutral(), row), expected,
                                   atol=1e-9, err_msg=finger)


def test_fingers_point_along_palm_y_at_zero(model: KinematicModel) -> None:
    for finger in digits(model):
        if finger == "thumb":
            continue
        start = np.array(ANCHORS[finger])
        length = sum(model.link(f"{finger}.{part}").length
                     for part in ("proximal", "middle", "distal"))
        tip = model.link(f"{finger}.tip").row
        np.testing.assert_allclose(origin_in_palm(model, model.neutral(), tip),
                                   start + np.array([0.0, length, 0.0]), atol=1e-9)


@pytest.mark.parametrize("name", ["hand", "mouse-hand", "two-finger", "cardboard-hand"])
def test_positive_flexion_moves_tips_to_the_palmar_side(name: str) -> None:
    model = load_model(name)
    checked = flexion_states(model)
    assert checked
    for finger, state in checked:
        shift = tip_shift_in_palm(model, finger, state)
        assert shift[2] > 1.0, state  # palmar side is +z of the palm frame
        assert abs(shift[0]) < 1e-9, state  # planar finger: no sideways motion


@pytest.mark.parametrize("name", ["hand", "mouse-hand", "cardboard-hand"])
def test_positive_abduction_moves_fingers_to_the_little_finger_side(name: str) -> None:
    model = load_model(name)
    for finger in FINGERS:
        if f"{finger}.abd" in model.state_names:
            shift = tip_shift_in_palm(model, finger, f"{finger}.abd")
            assert shift[0] < -1.0, finger
            assert abs(shift[2]) < 1e-9, finger


def test_flexion_is_relative_to_the_palm_not_the_world() -> None:
    model = load_model("cardboard-hand")
    q = model.neutral()
    q[0:4] = (math.cos(1.0), math.sin(1.0) * 0.6, 0.0, math.sin(1.0) * 0.8)  # unit quaternion
    q[4:7] = (100.0, -50.0, 400.0)
    assert tip_shift_in_palm(model, "ring", "ring.pip", q=q)[2] > 1.0


# --------------------------------------------------------------------------- mouse-hand
def test_mouse_hand_palm_rests_flat_on_the_table() -> None:
    model = load_model("mouse-hand")
    T = palm_pose(model, model.neutral())
    np.testing.assert_allclose(T[:3, :3], np.diag([-1.0, 1.0, -1.0]), atol=1e-12)
    palm = model.link("palm")
    centre = T[:3, :3] @ palm.centre + T[:3, 3]
    assert centre[2] == pytest.approx(palm.size[2] / 2)  # half the slab thickness
    corners = np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)])
    world = (T[:3, :3] @ (np.array(palm.centre) + corners * np.array(palm.size) / 2).T).T
    assert (world + T[:3, 3])[:, 2].min() == pytest.approx(0.0, abs=1e-9)


def test_mouse_hand_digits_lie_in_the_slab_mid_plane() -> None:
    model = load_model("mouse-hand")
    kin = forward_kinematics(model, model.neutral())
    tips, _ = kin.tip_centres()
    start, end, _ = kin.link_segments()
    np.testing.assert_allclose(tips[:, 2], REST_HEIGHT, atol=1e-9)
    np.testing.assert_allclose(start[:, 2], REST_HEIGHT, atol=1e-9)
    np.testing.assert_allclose(end[:, 2], REST_HEIGHT, atol=1e-9)


def test_mouse_hand_palm_slides_and_turns_in_the_table_plane() -> None:
    model = load_model("mouse-hand")
    q = model.neutral()
    q[model.state_index("palm.x")] = 120.0
    q[model.state_index("palm.y")] = -40.0
    q[model.state_index("palm.rot")] = math.pi / 2
    T = palm_pose(model, q)
    np.testing.assert_allclose(T[:3, 3], (120.0, -40.0, REST_HEIGHT), atol=1e-9)
    # counterclockwise seen from above: the fingers (palm +y) turn from world +y to -x
    np.testing.assert_allclose(T[:3, 1], (-1.0, 0.0, 0.0), atol=1e-12)
    np.testing.assert_allclose(T[:3, 2], (0.0, 0.0, -1.0), atol=1e-12)


def test_mouse_hand_index_extension_raises_the_pole() -> None:
    """Lifting the index tip (the pole height) is a negative index.mcp (extension)."""
    model = load_model("mouse-hand")
    i = model.state_index("index.mcp")
    angles = np.linspace(0.0, model.lower[i], 7)
    q = np.tile(model.neutral(), (len(angles), 1))
    q[:, i] = angles
    kin = forward_kinematics(model, q)
    height = kin.T_world_shape[:, model.link("index.tip").row, 2, 3]
    assert np.all(np.diff(height) > 0.0)
    finger = 45.0 + 26.0 + 24.0
    assert height[-1] == pytest.approx(REST_HEIGHT + finger * math.sin(math.radians(30.0)))


def test_mouse_hand_buttons_turn_in_the_table_plane() -> None:
    model = load_model("mouse-hand")
    little = tip_shift_in_palm(model, "little", "little.abd")
    thumb = tip_shift_in_palm(model, "thumb", "thumb.abd")
    assert little[0] < -1.0 and abs(little[2]) < 1e-9  # away from the index finger
    assert thumb[0] > 1.0 and abs(thumb[2]) < 1e-9  # away from the fingers
    assert abs(tip_shift_in_palm(model, "thumb", "palm.x")[2]) < 1e-9


def test_mouse_hand_thumb_rests_spread_from_the_index() -> None:
    model = load_model("mouse-hand")
    kin = forward_kinematics(model, model.neutral())
    T = kin.T_world_shape[0, model.link("thumb.metacarpal").row]
    palm = palm_pose(model, model.neutral())
    direction = palm[:3, :3].T @ T[:3, 0]
    assert math.degrees(math.atan2(direction[0], direction[1])) == pytest.approx(35.0)


# --------------------------------------------------------------------------- two-finger
def test_two_finger_palm_translates_along_world_axes_only() -> None:
    model = load_model("two-finger")
    q = model.neutral()
    q[:3] = (10.0, -20.0, 30.0)
    T = palm_pose(model, q)
    np.testing.assert_allclose(T[:3, :3], np.eye(3), atol=1e-12)
    np.testing.assert_allclose(T[:3, 3], (10.0, -20.0, 30.0), atol=1e-9)


# ----------------------------------------------------------------------- cardboard-hand
def test_cardboard_palm_is_a_thin_plane_through_the_anchors() -> None:
    palm = load_model("cardboard-hand").link("palm")
    assert palm.size[2] <= 2.0
    assert palm.centre[2] == 0.0


@pytest.mark.parametrize("name", ["hand", "cardboard-hand"])
def test_thumb_signs(name: str) -> None:
    """Positive abduction lifts the thumb palmar; positive in-plane angles extend it."""
    model = load_model(name)
    for state in ("thumb.cmc_abd", "thumb.mp_abd"):
        if state in model.state_names:
            assert tip_shift_in_palm(model, "thumb", state)[2] > 1.0, state  # palmar
    for state in ("thumb.cmc_flex", "thumb.mp", "thumb.ip"):
        shift = tip_shift_in_palm(model, "thumb", state)
        assert shift[0] > 1.0, state  # away from the fingers
        assert abs(shift[2]) < 1e-9, state


def test_cardboard_hand_is_the_hand_without_the_thumb_mp_abduction() -> None:
    """Shared states have the same limits and, with thumb.mp_abd = 0, the same pose."""
    hand, card = load_model("hand"), load_model("cardboard-hand")
    assert set(card.state_names) == set(hand.state_names) - {"thumb.mp_abd"}
    shared = [hand.state_index(name) for name in card.state_names]
    np.testing.assert_array_equal(card.lower, hand.lower[shared])
    np.testing.assert_array_equal(card.upper, hand.upper[shared])
    rng = np.random.default_rng(7)
    q_hand = hand.neutral()
    joints = np.isfinite(hand.lower)
    q_hand[joints] = rng.uniform(hand.lower[joints], hand.upper[joints])
    q_hand[:4] = (0.5, 0.5, -0.5, 0.5)
    q_hand[4:7] = (10.0, 20.0, 300.0)
    q_hand[hand.state_index("thumb.mp_abd")] = 0.0
    kin_hand = forward_kinematics(hand, q_hand)
    kin_card = forward_kinematics(card, q_hand[shared])
    for link in card.links:
        if link.kind != "palm":
            np.testing.assert_allclose(
                kin_card.T_world_shape[0, link.row],
                kin_hand.T_world_shape[0, hand.link(link.name).row], atol=1e-9,
                err_msg=link.name,
            )
