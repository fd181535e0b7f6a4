"""The palm mapping of the 3D mouse (a full hand, its start pose as the table), checked
against geometry worked out by hand."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from digiteyes import load_model
from digiteyes.apps.mouse3d import TableMouse
from digiteyes.apps.mouse_stream import mouse_mapping
from digiteyes.apps.palm_mouse import PalmMouse
from digiteyes.errors import StateError

HAND = load_model("hand")
INDEX_LENGTH_MM = 95.0  # Appendix A: MCP to tip centre, 45 + 26 + 24 mm


def posed(rotvec_deg, position_mm, **angles) -> np.ndarray:
    q = HAND.neutral()
    q[:4] = Rotation.from_rotvec(np.radians(rotvec_deg)).as_quat(scalar_first=True)
    q[4:7] = position_mm
    for name, value in angles.items():
        q[HAND.state_index(name.replace("_", ".", 1))] = np.radians(value)
    return q


START = posed([30.0, -20.0, 50.0], [10.0, -20.0, 500.0])


def test_the_start_is_the_origin_and_a_raised_index_lifts_the_pole_by_l_sin_theta():
    mouse = PalmMouse.from_start(HAND, START)
    np.testing.assert_allclose(mouse.pole(START), 0.0, atol=1e-9)
    for theta in (5.0, 17.0, 29.0):  # MCP extension (negative flexion) of a straight finger
        raised = START.copy()
        raised[HAND.state_index("index.mcp")] = -np.radians(theta)
        np.testing.assert_allclose(mouse.pole(raised),
                                   [0.0, 0.0, INDEX_LENGTH_MM * np.sin(np.radians(theta))],
                                   atol=1e-9)


def test_the_base_moves_with_the_palm_in_the_start_palm_frame():
    """x towards the little finger, y along the fingers, z out of the back of the hand."""
    mouse = PalmMouse.from_start(HAND, START)
    R_world_palm = Rotation.from_quat(START[:4], scalar_first=True).as_matrix()
    for along_palm, expected in (([0.0, 20.0, 0.0], [0.0, 20.0, 0.0]),  # towards fingers
                                 ([-15.0, 0.0, 0.0], [15.0, 0.0, 0.0]),  # little's side
                                 ([0.0, 0.0, -8.0], [0.0, 0.0, 0.0])):  # lifted: no base move
        moved = START.copy()
        moved[4:7] += R_world_palm @ along_palm
        pole = mouse.pole(moved)
        np.testing.assert_allclose(pole[:2], expected[:2], atol=1e-9)
        assert pole[2] == pytest.approx(0.0, abs=1e-9)  # the height is the finger's alone


def test_the_mapping_does_not_depend_on_the_world_frame():
    """The same hand motion seen from another world frame gives the same pole."""
    motion = posed([35.0, -10.0, 45.0], [40.0, 5.0, 480.0], index_mcp=-20.0,
                   thumb_cmc_flex=18.0)
    R = Rotation.from_rotvec([0.3, -1.1, 0.4])
    t = np.array([100.0, -50.0, 30.0])

    def moved(q):
        out = q.copy()
        out[:4] = (R * Rotation.from_quat(q[:4], scalar_first=True)).as_quat(scalar_first=True)
        out[4:7] = R.apply(q[4:7]) + t
        return out

    here = PalmMouse.from_start(HAND, START)
    there = PalmMouse.from_start(HAND, moved(START))
    np.testing.assert_allclose(there.pole(moved(motion)), here.pole(motion), atol=1e-8)
    assert there.buttons(moved(motion)) == here.buttons(motion)


def test_buttons_press_when_a_digit_spreads_past_the_threshold_beyond_its_start():
    start = posed([0.0, 0.0, 0.0], [0.0, 0.0, 400.0], thumb_cmc_flex=5.0)
    mouse = PalmMouse.from_start(HAND, start, threshold_deg=10.0)
    assert mouse.buttons(start) == {"thumb": False, "little": False}
    # thumb.cmc_flex turns the thumb in the palm plane: its spread follows the joint
    spread = posed([0.0, 0.0, 0.0], [0.0, 0.0, 400.0], thumb_cmc_flex=14.0)
    assert mouse.buttons(spread) == {"thumb": False, "little": False}  # 9 deg past the start
    spread = posed([0.0, 0.0, 0.0], [0.0, 0.0, 400.0], thumb_cmc_flex=16.0)
    assert mouse.buttons(spread) == {"thumb": True, "little": False}
    little = posed([0.0, 0.0, 0.0], [0.0, 0.0, 400.0], thumb_cmc_flex=5.0, little_abd=12.0)
    assert mouse.buttons(little) == {"thumb": False, "little": True}
    closed = posed([0.0, 0.0, 0.0], [0.0, 0.0, 400.0], thumb_cmc_flex=-20.0, little_abd=-12.0)
    assert mouse.buttons(closed) == {"thumb": False, "little": False}
    batch = mouse.buttons(np.stack([start, spread, little]))
    np.testing.assert_array_equal(batch["thumb"], [False, True, False])
    np.testing.assert_array_equal(batch["little"], [False, False, True])
    assert mouse.pole(np.stack([start, spread])).shape == (2, 3)


def test_a_mirrored_hand_moves_the_pole_the_same_way_for_the_same_real_motion():
    """A left hand tracked as the mirror image's right hand: a real move towards the user's
    right (the little finger's side of a right hand, the thumb's side of a left hand
    lying palm down) gives +x for both."""
    right = PalmMouse.from_start(HAND, START)
    left = PalmMouse.from_start(HAND, START, mirrored=True)
    R_world_palm = Rotation.from_quat(START[:4], scalar_first=True).as_matrix()
    towards_index = START.copy()
    towards_index[4:7] += R_world_palm @ [10.0, 0.0, 0.0]
    assert right.pole(towards_index)[0] == pytest.approx(-10.0)
    assert left.pole(towards_index)[0] == pytest.approx(10.0)


def test_the_stream_maps_the_reduced_model_by_the_table_and_a_full_hand_by_its_palm():
    mouse_hand = load_model("mouse-hand")
    assert isinstance(mouse_mapping(mouse_hand, mouse_hand.neutral()), TableMouse)
    assert isinstance(mouse_mapping(HAND, START), PalmMouse)
    two = load_model("two-finger")
    with pytest.raises(StateError, match="needs a full hand"):
        PalmMouse.from_start(two, two.neutral())


def test_a_replayed_full_hand_run_is_mapped_by_its_palm(tmp_path):
    """``digiteyes mouse --replay RUN`` of a full-hand track: the model comes from the
    log's header and the pole from the palm mapping of its first state."""
    from digiteyes.apps.mouse_stream import open_mouse_stream
    from digiteyes.io import StateLogWriter

    raised = START.copy()
    raised[HAND.state_index("index.mcp")] = -np.radians(20.0)
    with StateLogWriter(tmp_path / "states.csv", HAND) as log:
        for i, q in enumerate((START, raised)):
            log.append(i, q, time_s=0.0, lost=False, residual_rms_px=0.0, iterations=1)
    stream = open_mouse_stream(replay=tmp_path, fps=1000.0)
    frames = list(stream.frames)
    assert stream.model.name == "hand" and isinstance(frames[0].mapping, PalmMouse)
    np.testing.assert_allclose(frames[0].pole, 0.0, atol=1e-9)
    assert frames[1].pole[2] == pytest.approx(INDEX_LENGTH_MM * np.sin(np.radians(20.0)))


def test_a_replayed_run_of_a_measured_hand_is_mapped_at_its_size(tmp_path):
    """A keypoint track that measured the hand at 0.9 (``hand_scale``): the replay's pole
    height is that of the smaller finger (0.9 of the model's for the same raise)."""
    from digiteyes.apps.mouse_stream import open_mouse_stream
    from digiteyes.io import StateLogWriter

    raised = START.copy()
    raised[HAND.state_index("index.mcp")] = -np.radians(20.0)
    with StateLogWriter(tmp_path / "states.csv", HAND, hand_scale=True) as log:
        for i, q in enumerate((START, raised)):
            log.append(i, q, time_s=0.0, lost=False, residual_rms_px=0.0, iterations=1,
                       hand_scale=0.9)
    frames = list(open_mouse_stream(replay=tmp_path, fps=1000.0).frames)
    assert frames[1].pole[2] == pytest.approx(0.9 * INDEX_LENGTH_MM * np.sin(np.radians(20.0)))


def test_a_replayed_left_hand_run_moves_the_pole_as_the_real_hand_moves(tmp_path):
    """A left hand's run holds the mirror image's states (``summary.json`` says
    ``start.hand: left``): its replay maps them as mirrored, so the same states move the
    pole the other way in x than a right hand's run does."""
    import json

    from digiteyes.apps.mouse_stream import open_mouse_stream
    from digiteyes.io import StateLogWriter

    moved = START.copy()
    moved[4:7] += Rotation.from_quat(START[:4], scalar_first=True).apply([10.0, 0.0, 0.0])
    poles = {}
    for side in ("right", "left"):
        run = tmp_path / side
        run.mkdir()
        with StateLogWriter(run / "states.csv", HAND) as log:
            for i, q in enumerate((START, moved)):
                log.append(i, q, time_s=0.0, lost=False, residual_rms_px=0.0, iterations=1)
        (run / "summary.json").write_text(json.dumps({"fps": 10.0, "start": {"hand": side}}))
        poles[side] = list(open_mouse_stream(replay=run, fps=1000.0).frames)[1].pole
    assert poles["right"][0] == pytest.approx(-10.0) and poles["left"][0] == pytest.approx(10.0)
