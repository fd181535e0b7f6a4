"""Synthetic scenarios: determinism, lengths, limits, camera coverage, and the motion
properties each one promises (docs/scenarios.md)."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.signal import find_peaks

from digiteyes.errors import DigitEyesError
from digiteyes.kinematics import forward_kinematics, validate_state
from digiteyes.kinematics.anatomy import basis_configurations, basis_joint_angles
from digiteyes.kinematics.keypoints import keypoints
from digiteyes.synth import RenderOptions, render_views
from digiteyes.synth.scenarios import (
    SCENARIOS,
    build_scenario,
)

EXPECTED = {  # name: (frames, fps, cameras)
    "whole-hand": (200, 10.0, 2),
    "mouse": (500, 10.0, 1),
    "two-finger-occlusion": (80, 15.0, 1),
    "natural": (200, 30.0, 2),
    "fast": (200, 10.0, 2),
    "hand-mouse": (500, 10.0, 1),
}


@pytest.fixture(scope="module")
def built():
    """Every thesis scenario at seed 0, built once (the camera setups: test_setups.py)."""
    return {name: build_scenario(name, seed=0) for name in EXPECTED}


def projected_keypoints(scenario):
    """(C, T, K, 2) pixels of the renderer's keypoints, computed here from the states."""
    points = keypoints(scenario.model, forward_kinematics(scenario.model, scenario.states))[1]
    return np.stack([cam.project(points) for cam in scenario.rig]), points


def joints(scenario, names):
    return scenario.states[:, [scenario.model.state_index(n) for n in names]]


# ------------------------------------------------------------------ common properties
def test_registry_lists_the_six_scenarios_and_the_setups():
    from digiteyes.synth.setups import SETUP_SCENARIOS

    assert set(SCENARIOS) == set(EXPECTED) | set(SETUP_SCENARIOS)


@pytest.mark.parametrize("name", list(EXPECTED))
def test_lengths_rates_cameras_and_initial_state(built, name):
    s = built[name]
    frames, fps, cameras = EXPECTED[name]
    assert s.name == name
    assert s.states.shape == (frames, s.model.n_q) and s.n_frames == frames
    assert s.fps == fps and len(s.rig) == cameras
    np.testing.assert_array_equal(s.initial_state, s.states[0])
    assert len(s.metadata["image_speed_px"]) == frames


@pytest.mark.parametrize("name", list(EXPECTED))
def test_states_are_valid_and_inside_the_joint_limits(built, name):
    s = built[name]
    validate_state(s.model, s.states)  # finite, unit base quaternion
    assert np.all(s.states >= s.model.lower) and np.all(s.states <= s.model.upper)


@pytest.mark.parametrize("name", list(EXPECTED))
def test_same_seed_gives_identical_states(built, name):
    again = build_scenario(name, seed=0)
    np.testing.assert_array_equal(again.states, built[name].states)
    assert again.metadata == built[name].metadata


@pytest.mark.parametrize("name", ["whole-hand", "natural", "fast"])
def test_different_seeds_give_different_motion(built, name):
    other = build_scenario(name, seed=1)
    assert np.abs(other.states - built[name].states).max() > 0.05


def test_mouse_seed_changes_only_the_last_phase(built):
    other = build_scenario("mouse", seed=1)
    np.testing.assert_array_equal(other.states[:351], built["mouse"].states[:351])
    assert np.abs(other.states[360:] - built["mouse"].states[360:]).max() > 0.05


def test_two_finger_motion_is_scripted(built):
    np.testing.assert_array_equal(build_scenario("two-finger-occlusion", seed=5).states,
                                  built["two-finger-occlusion"].states)


@pytest.mark.parametrize("name", list(EXPECTED))
def test_hand_stays_in_every_image(built, name):
    s = built[name]
    pixels, points = projected_keypoints(s)
    for cam, w in zip(s.rig, pixels, strict=True):
        assert np.all(cam.depth(points) > 100.0)
        assert np.all(cam.in_image(w, margin=20.0)), f"{cam.name} loses the hand"


@pytest.mark.parametrize("name", list(EXPECTED))
def test_image_speed_metadata_matches_the_keypoints(built, name):
    s = built[name]
    pixels, _ = projected_keypoints(s)
    step = np.linalg.norm(np.diff(pixels, axis=1), axis=-1).max(axis=(0, 2))
    np.testing.assert_allclose(s.metadata["image_speed_px"][1:], step, atol=1e-3)
    assert s.metadata["image_speed_px"][0] == 0.0


def test_unknown_scenario_names_the_valid_ones():
    with pytest.raises(DigitEyesError, match="valid scenarios are whole-hand, mouse"):
        build_scenario("whole-hands")


@pytest.mark.parametrize("n_frames", [0, -3, 2.5])
def test_bad_frame_counts_are_refused(n_frames):
    with pytest.raises(DigitEyesError, match="positive integer"):
        build_scenario("whole-hand", n_frames=n_frames)


@pytest.mark.parametrize("name", ["whole-hand", "natural", "mouse"])
def test_shorter_sequences_are_prefixes(built, name):
    short = build_scenario(name, seed=0, n_frames=37)
    np.testing.assert_array_equal(short.states, built[name].states[:37])
    assert len(short.metadata["image_speed_px"]) == 37


def test_longer_scripted_sequences_hold_the_last_state(built):
    s = build_scenario("two-finger-occlusion", n_frames=95)
    np.testing.assert_array_equal(s.states[:80], built["two-finger-occlusion"].states)
    np.testing.assert_array_equal(s.states[80:], np.repeat(s.states[79:80], 15, axis=0))


def test_image_up_is_world_up(built):
    """Every camera is upright: a point above the hand appears higher in the image."""
    for s in built.values():
        centre = keypoints(s.model, forward_kinematics(s.model, s.states[0]))[1][0].mean(0)
        for cam in s.rig:
            low, high = cam.project(np.stack([centre, centre + np.array([0.0, 0.0, 30.0])]))
            assert high[1] < low[1] - 5.0


# ------------------------------------------------------------------ whole hand
def _link_axes(scenario, frames):
    kin = forward_kinematics(scenario.model, scenario.states[frames])
    start, end, idx = kin.link_segments()
    return start, end, idx


def _adjacent(model, idx):
    """(L, L) bool: cylinder links that share a joint (parent and child in a chain)."""
    row_link = {model.links[i].row: k for k, i in enumerate(idx)}
    adjacent = np.eye(len(idx), dtype=bool)
    for k, i in enumerate(idx):
        row = model.parent[model.links[i].row]
        while row >= 0 and row not in row_link:
            row = model.parent[row]
        if row >= 0:
            adjacent[k, row_link[row]] = adjacent[row_link[row], k] = True
    return adjacent


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_whole_hand_keeps_every_link_axis_in_view(seed):
    """No self-occlusion: in both cameras, no link's silhouette covers the axis of another
    (non-adjacent) link, i.e. the projected axes stay further apart than the larger
    projected radius. Only the proximal phalanges of the middle and ring fingers, whose
    bases overlap in the model itself (thesis Sec. 4.3.3), are exempt."""
    s = build_scenario("whole-hand", seed=seed)
    frames = np.arange(0, s.n_frames, 2)
    start, end, idx = _link_axes(s, frames)
    names = [s.model.links[i].name for i in idx]
    allowed = _adjacent(s.model, idx)
    a, b = names.index("middle.proximal"), names.index("ring.proximal")
    allowed[a, b] = allowed[b, a] = True
    radius = np.array([s.model.links[i].radius for i in idx])
    samples = np.linspace(0.0, 1.0, 12)
    points = start[:, :, None] + samples[:, None] * (end - start)[:, :, None]  # (T, L, S, 3)
    for cam in s.rig:
        w = cam.project(points)
        r_px = cam.K[0, 0] * radius[None, :, None] / cam.depth(points)
        gap = np.linalg.norm(w[:, :, None, :, None] - w[:, None, :, None, :], axis=-1)
        larger = np.maximum(r_px[:, :, None, :, None], r_px[:, None, :, None, :])
        clearance = (gap - larger).min(axis=(-1, -2))  # (T, L, L)
        clearance[:, allowed] = np.inf
        t, i, j = np.unravel_index(np.argmin(clearance), clearance.shape)
        assert clearance[t, i, j] > 0.0, (
            f"seed {seed} {cam.name} frame {frames[t]}: {names[i]} covers {names[j]}")


@pytest.mark.parametrize("seed", [0, 1])
def test_whole_hand_links_keep_their_visible_area(seed):
    """Rendered label images: every cylinder link shows at least 40% of the area of its
    projected cylinder (2 r L in pixels) and every fingertip centre is visible."""
    s = build_scenario("whole-hand", seed=seed)
    for t in range(0, s.n_frames, 10):
        views = render_views(s.model, s.states[t], s.rig, RenderOptions(), 0)
        start, end, idx = _link_axes(s, t)
        radius = np.array([s.model.links[i].radius for i in idx])
        for cam, view in zip(s.rig, views, strict=True):
            area = np.bincount(view.labels[view.labels >= 0], minlength=len(s.model.links))
            length_px = np.linalg.norm(cam.project(end) - cam.project(start), axis=1)
            r_px = cam.K[0, 0] * radius / cam.depth((start + end) / 2)
            ratio = area[idx] / np.maximum(2 * r_px * length_px, 1.0)
            worst = np.argmin(ratio)
            assert ratio[worst] > 0.4, (f"frame {t} {cam.name}: "
                                        f"{s.model.links[idx[worst]].name} {ratio[worst]:.2f}")
            tips = [k for k, n in enumerate(view.keypoint_names) if n.endswith(".tip")]
            assert view.visible[tips].all(), f"frame {t} {cam.name}: a fingertip is hidden"


def test_whole_hand_motion_stays_inside_a_search_window(built):
    speed = np.array(built["whole-hand"].metadata["image_speed_px"])
    assert speed.max() < 8.0
    assert speed[1:].mean() > 1.0  # and it does move


def test_whole_hand_is_palm_down_facing_the_cameras(built):
    s = built["whole-hand"]
    kin = forward_kinematics(s.model, s.states)
    R = kin.T_world_frame[:, s.model.root, :3, :3]
    palmar = R[:, :, 2]
    assert np.all(palmar[:, 2] < -np.cos(np.radians(30)))  # within 30 deg of straight down
    centre = R @ np.array([0.0, 46.0, 0.0]) + kin.T_world_frame[:, s.model.root, :3, 3]
    for cam in s.rig:  # the back of the hand faces every camera
        to_cam = cam.centre_world - centre
        assert np.all(np.einsum("ti,ti->t", -palmar, to_cam) > 0)


def test_whole_hand_articulates_every_finger_and_the_thumb(built):
    s = built["whole-hand"]
    for name in ("index.mcp", "middle.pip", "ring.dip", "little.mcp", "thumb.cmc_flex",
                 "thumb.ip", "palm.x", "palm.z"):
        values = joints(s, [name])[:, 0]
        assert np.ptp(values) > (10.0 if name.startswith("palm") else np.radians(8)), name


# ------------------------------------------------------------------ fast
def test_fast_speed_grows_linearly_past_the_search_window(built):
    s = built["fast"]
    speed = np.array(s.metadata["image_speed_px"])[1:]
    target = np.array(s.metadata["target_speed_px"])[1:]
    np.testing.assert_allclose(speed, target, rtol=1e-3)
    assert speed[0] < 3.0 and speed[-1] > 30.0
    assert np.all(np.diff(speed) > 0)


def test_fast_ramp_follows_the_requested_length():
    s = build_scenario("fast", n_frames=40)
    speed = np.array(s.metadata["image_speed_px"])
    assert len(speed) == 40 and speed[1] < 3.0 and speed[-1] > 30.0


# ------------------------------------------------------------------ mouse
def test_mouse_phases(built):
    s = built["mouse"]
    height = np.array(s.metadata["index_tip_height_mm"])
    kin = forward_kinematics(s.model, s.states)
    tip = kin.T_world_shape[:, s.model.link("index.tip").row, :3, 3]
    np.testing.assert_allclose(height, tip[:, 2], atol=1e-3)

    peaks, _ = find_peaks(height[:150], prominence=10.0)
    assert len(peaks) == 2, "the index is raised and lowered twice in frames 0-150"
    assert height[:150].max() - height[:150].min() > 25.0

    thumb = joints(s, ["thumb.abd"])[:, 0]
    others = [n for n in s.model.state_names if n != "thumb.abd"]
    assert np.ptp(thumb[:150]) == 0 and np.ptp(thumb[200:351]) == 0
    assert np.ptp(thumb[150:201]) > np.radians(15)
    assert np.ptp(joints(s, others)[150:201], axis=0).max() == 0, "only the thumb moves"

    moving = ["palm.x", "palm.y"]
    still = [n for n in s.model.state_names if n not in moving]
    assert np.ptp(joints(s, still)[200:351], axis=0).max() == 0
    assert np.ptp(joints(s, moving)[200:351], axis=0).min() > 40.0
    assert np.ptp(height[150:351]) < 1e-9, "the pole height is held from frame 150 to 350"

    assert np.all(np.ptp(s.states[350:], axis=0) > 0), "every state moves in 350-500"


# ------------------------------------------------------------------ two fingers
def test_two_finger_only_the_index_curls(built):
    s = built["two-finger-occlusion"]
    assert np.ptp(joints(s, ["palm.x", "palm.y", "palm.z"]), axis=0).max() == 0
    assert np.ptp(joints(s, ["middle.pip", "middle.dip"]), axis=0).max() == 0
    assert 0 < np.ptp(joints(s, ["middle.mcp"])) <= np.radians(6.001)
    curl = joints(s, ["index.mcp", "index.pip", "index.dip"])
    assert np.all(np.diff(curl, axis=0) >= 0) and np.all(curl[-1] > np.radians(50))
    speed = np.array(s.metadata["index_tip_speed_px"])[1:]
    assert 2.5 < speed.mean() < 3.5  # thesis Sec. 4.4.2: about 3 px per frame


def test_two_finger_index_hides_the_middle_finger_and_palm(built):
    """Against the same frame rendered with the index finger straight, the curling index
    covers a large part of the middle finger's two inner phalanges and of the palm."""
    s = built["two-finger-occlusion"]
    names = [link.name for link in s.model.links]
    index_labels = [k for k, n in enumerate(names) if n.startswith("index")]
    curl = [s.model.state_index(n) for n in ("index.mcp", "index.pip", "index.dip")]
    parts = [names.index(n) for n in ("middle.proximal", "middle.middle", "palm")]
    lost = np.zeros(len(parts))
    for t in range(4, s.n_frames, 4):
        straight = s.states[t].copy()
        straight[curl] = 0.0
        ref = render_views(s.model, straight, s.rig, RenderOptions(), 0)[0].labels
        labels = render_views(s.model, s.states[t], s.rig, RenderOptions(), 0)[0].labels
        for p, k in enumerate(parts):
            covered = (ref == k) & (labels != k)
            assert np.isin(labels[covered], index_labels).all(), names[k]
            lost[p] = max(lost[p], covered.sum() / (ref == k).sum())
    assert np.all(lost > 0.3), dict(zip([names[k] for k in parts], lost, strict=True))


# ------------------------------------------------------------------ natural
def test_basis_configurations():
    names = basis_configurations()
    assert len(names) == 28 == len(set(names))
    assert all(len(n) == 5 and set(n) <= {"E", "C"} for n in names)
    assert "EEEEE" in names and "CCCCC" in names


def test_natural_moves_on_straight_lines_between_basis_configurations(built):
    s = built["natural"]
    joint = np.ones(s.model.n_q, dtype=bool)
    joint[s.model.base_state:s.model.base_state + 7] = False
    basis = {b: np.array(v)[joint] for b, v in s.metadata["basis_configurations"].items()}
    for b in basis:
        np.testing.assert_allclose(basis[b], basis_joint_angles(s.model, b)[joint], atol=1e-6)
    q = s.states[:, joint]
    np.testing.assert_allclose(q[0], basis["EEEEE"], atol=1e-12)
    covered = np.zeros(s.n_frames, dtype=bool)
    moves = s.metadata["basis_moves"]
    assert len(moves) >= 3
    for begin, end, a, b in moves:
        frames = np.arange(begin, min(end, s.n_frames - 1) + 1)
        step = basis[b] - basis[a]
        lam = (q[frames] - basis[a]) @ step / (step @ step)
        np.testing.assert_allclose(q[frames], basis[a] + lam[:, None] * step, atol=1e-9)
        assert np.all((lam >= -1e-12) & (lam <= 1 + 1e-12)) and np.all(np.diff(lam) >= 0)
        covered[frames] = True
    held = np.flatnonzero(~covered)
    distance = np.min([np.abs(q[held] - v).max(axis=1) for v in basis.values()], axis=0)
    assert distance.max() < 1e-9, "between moves the hand holds a basis configuration"


def test_natural_global_rotation_is_slow(built):
    s = built["natural"]
    k = s.model.base_state
    quat = s.states[:, k:k + 4]
    turn = 2 * np.arccos(np.clip(np.abs(np.sum(quat[1:] * quat[:-1], axis=1)), 0, 1))
    assert np.degrees(turn).max() < 1.0  # degrees per frame at 30 Hz
    assert np.degrees(2 * np.arccos(np.abs(quat @ quat[0]).min())) > 5.0  # but it turns


def test_hand_mouse_plays_the_mouse_motion_with_the_full_hand(built):
    """Same channels as ``mouse``: the palm mapping's pole follows the mouse's (base
    moves and index height), and the thumb button is pressed exactly in the button event
    of ``mouse`` (thumb spread past 12.5 degrees)."""
    from digiteyes.apps.mouse3d import buttons_from_state, pole_from_state
    from digiteyes.apps.palm_mouse import PalmMouse

    hand, mouse = built["hand-mouse"], built["mouse"]
    palm = PalmMouse.from_start(hand.model, hand.states[0])
    pole, table = palm.pole(hand.states), pole_from_state(mouse.model, mouse.states)
    # base: the palm slides by the mouse's x, y (no turn before frame 350)
    moved = np.hypot(*(pole[:, :2] - pole[0, :2]).T)
    assert np.abs(moved - np.hypot(*(table[:, :2] - table[0, :2]).T))[:350].max() < 1e-6
    raised = pole[:, 2]
    assert raised[0] == pytest.approx(0.0, abs=1e-9) and raised[40] > 30.0
    pressed = palm.buttons(hand.states)["thumb"]
    np.testing.assert_array_equal(pressed[:350],
                                  buttons_from_state(mouse.model, mouse.states)["thumb"][:350])
