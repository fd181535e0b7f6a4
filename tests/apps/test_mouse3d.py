"""The 3D-mouse mapping (thesis Sec. 4.3.4) against hand-computed poles and buttons.

Geometry of ``mouse-hand.dh`` used below: the palm frame is 7.5 mm above the table and
palm-down, the index finger lies in the palm plane with phalanges of 45, 26 and 24 mm and
a 9 mm tip sphere; positive MCP/PIP/DIP flex towards the palmar side, i.e. down.
"""

import cv2
import numpy as np
import pytest

from digiteyes import load_model
from digiteyes.apps.mouse3d import (
    buttons_from_state,
    plot_mouse_pole,
    pole_from_state,
    write_mouse_pole_plot,
)
from digiteyes.errors import StateError
from digiteyes.kinematics import forward_kinematics

AXIS_HEIGHT = 7.5
PHALANGES = (45.0, 26.0, 24.0)
TIP_RADIUS = 9.0


@pytest.fixture(scope="module")
def mouse():
    return load_model("mouse-hand")


def _state(model, **values):
    q = model.neutral()
    for name, value in values.items():
        q[model.state_index(name.replace("_", "."))] = value
    return q


def test_finger_flat_on_the_table(mouse):
    q = _state(mouse, palm_x=30.0, palm_y=-20.0, palm_rot=0.4)
    pole = pole_from_state(mouse, q)
    assert pole.shape == (3,)
    np.testing.assert_allclose(pole, [30.0, -20.0, AXIS_HEIGHT - TIP_RADIUS], atol=1e-9)
    kin = forward_kinematics(mouse, q)
    tip = mouse.link("index.tip")
    assert pole[2] == pytest.approx(kin.T_world_shape[0, tip.row, 2, 3] - tip.radius)


@pytest.mark.parametrize("mcp_deg", [-30.0, -12.0, 20.0])
def test_mcp_lift_closed_form(mouse, mcp_deg):
    theta = np.radians(mcp_deg)
    q = _state(mouse, palm_x=-55.0, palm_y=12.0, palm_rot=-0.7, index_mcp=theta)
    expected = AXIS_HEIGHT - sum(PHALANGES) * np.sin(theta) - TIP_RADIUS
    assert pole_from_state(mouse, q)[2] == pytest.approx(expected, abs=1e-9)


def test_three_joint_closed_form_and_rotation_invariance(mouse):
    mcp, pip, dip = np.radians([-28.0, 8.0, 4.0])
    expected = (AXIS_HEIGHT - PHALANGES[0] * np.sin(mcp) - PHALANGES[1] * np.sin(mcp + pip)
                - PHALANGES[2] * np.sin(mcp + pip + dip) - TIP_RADIUS)
    rots = np.radians([-80.0, 0.0, 45.0])
    Q = np.stack([_state(mouse, palm_x=5.0 * i, palm_y=-3.0 * i, palm_rot=r, index_mcp=mcp,
                         index_pip=pip, index_dip=dip) for i, r in enumerate(rots)])
    pole = pole_from_state(mouse, Q)
    assert pole.shape == (3, 3)
    np.testing.assert_allclose(pole[:, 2], expected, atol=1e-9)
    np.testing.assert_allclose(pole[:, 0], [0.0, 5.0, 10.0], atol=1e-9)
    np.testing.assert_allclose(pole[:, 1], [0.0, -3.0, -6.0], atol=1e-9)


def test_other_digits_do_not_move_the_pole(mouse):
    q = _state(mouse, palm_x=10.0, index_mcp=np.radians(-20.0))
    moved = q.copy()
    moved[mouse.state_index("thumb.abd")] = np.radians(30.0)
    moved[mouse.state_index("little.abd")] = np.radians(-20.0)
    np.testing.assert_allclose(pole_from_state(mouse, moved), pole_from_state(mouse, q),
                               atol=1e-12)


def test_buttons_threshold(mouse):
    deg = np.radians
    q = _state(mouse, thumb_abd=deg(13.0), little_abd=deg(12.0))
    assert buttons_from_state(mouse, q) == {"thumb": True, "little": False}
    assert buttons_from_state(mouse, q, threshold_deg=11.0) == {"thumb": True, "little": True}
    assert buttons_from_state(mouse, q, threshold_deg=20.0) == {"thumb": False,
                                                                "little": False}
    adducted = _state(mouse, thumb_abd=deg(-25.0), little_abd=deg(-20.0))
    assert buttons_from_state(mouse, adducted) == {"thumb": False, "little": False}
    batch = np.stack([q, adducted, _state(mouse, little_abd=deg(20.0))])
    pressed = buttons_from_state(mouse, batch)
    np.testing.assert_array_equal(pressed["thumb"], [True, False, False])
    np.testing.assert_array_equal(pressed["little"], [False, False, True])


def test_errors(mouse):
    with pytest.raises(StateError):
        pole_from_state(mouse, np.zeros(mouse.n_q + 1))
    hand = load_model("hand")
    with pytest.raises(StateError, match=r"thumb\.abd"):
        buttons_from_state(hand, hand.neutral())


def test_pole_plot(mouse, tmp_path):
    t = np.arange(40)
    Q = np.stack([_state(mouse, palm_x=float(i), index_mcp=-np.radians(i)) for i in t])
    truth = pole_from_state(mouse, Q)
    fig = plot_mouse_pole(t, truth + 1.0, truth, phases=[(0, 20), (20, 40)])
    assert len(fig.axes) == 3
    path = write_mouse_pole_plot(tmp_path / "pole.png", t, truth + 1.0, truth)
    image = cv2.imread(str(path))
    assert image is not None and image.shape[0] > 100 and image.shape[1] > 100
