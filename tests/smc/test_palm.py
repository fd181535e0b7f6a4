"""Palm pose (Huang Sec. 4): factorisation under scaled orthography, perspective refinement,
ICP on a rendered frame."""

import numpy as np
import pytest

from digiteyes.camera import Camera
from digiteyes.kinematics.rotations import matrix_from_quaternion, quaternion_from_rotvec
from digiteyes.smc.likelihood import FingerGeometry, observe_edges
from digiteyes.smc.palm import (
    PalmPoseError,
    calibrate_palm_scale,
    icp_palm,
    nearest_edge_field,
    outline_visibility,
    palm_outline_points,
    palm_pose_from_correspondences,
    palm_pose_from_state,
    planar_pose_candidates,
    with_palm_pose,
)
from digiteyes.synth import render_views


def _angle_deg(Ra, Rb):
    return np.degrees(np.arccos(np.clip((np.trace(Ra.T @ Rb) - 1) / 2, -1, 1)))


@pytest.mark.parametrize("rotvec, tol", [((0.4, -0.3, 0.8), 1e-9), ((-0.9, 0.2, 0.1), 1e-9),
                                         ((0.0, 0.0, 2.0), 1e-3)])
def test_factorisation_recovers_pose_exactly_under_scaled_orthography(rotvec, tol):
    """Exact in general; face-on (third case) the tilt is a square root of a round-off-sized
    number, so it is recovered to about sqrt(machine epsilon) only."""
    rng = np.random.default_rng(1)
    R = matrix_from_quaternion(quaternion_from_rotvec(np.array(rotvec)))
    t = np.array([12.0, -7.0, 450.0])
    x = rng.uniform(-40, 40, (25, 2))
    P = x @ R[:, :2].T + t
    m = P[:, :2] / t[2]                     # scaled orthography: one depth t3 for all
    candidates = planar_pose_candidates(x, m)
    errors = [np.abs(Rc - R).max() + np.abs(tc - t).max() for Rc, tc in candidates]
    assert min(errors) < tol
    if len(candidates) == 2 and tol < 1e-6:  # the other solution mirrors the tilt
        Rm = candidates[int(np.argmax(errors))][0]
        np.testing.assert_allclose(Rm[:2, :2], R[:2, :2], atol=1e-9)


def test_factorisation_then_refinement_under_perspective():
    cam = Camera.look_at("c", eye=(0, 0, 0), target=(0, 0, 1), up=(0, -1, 0))
    R = matrix_from_quaternion(quaternion_from_rotvec(np.array([0.5, -0.3, 0.4])))
    T_cam_plane = np.eye(4)
    T_cam_plane[:3, :3], T_cam_plane[:3, 3] = R, (20.0, -10.0, 400.0)
    x = np.random.default_rng(2).uniform(-45, 45, (30, 2))
    p_cam = x @ R[:, :2].T + T_cam_plane[:3, 3]
    pixels = cam.project((cam.T_world_cam[:3, :3] @ p_cam.T).T + cam.T_world_cam[:3, 3])
    T0, _ = palm_pose_from_correspondences(cam, x, pixels, R, refine=False)
    assert _angle_deg(T0[:3, :3], R) < 8.0                      # close: orthographic guess
    T, rms = palm_pose_from_correspondences(cam, x, pixels, R)
    assert rms < 1e-4
    assert _angle_deg(T[:3, :3], R) < 1e-4
    np.testing.assert_allclose(T[:3, 3], T_cam_plane[:3, 3], atol=1e-3)
    with pytest.raises(PalmPoseError, match="collinear"):
        planar_pose_candidates(np.c_[np.arange(5.0), np.zeros(5)], np.zeros((5, 2)))


def test_icp_palm_pose_on_rendered_frame(natural_cardboard):
    model, cam, states = natural_cardboard
    geometry = FingerGeometry.of(model)
    q = states[10]
    image = render_views(model, q, [cam], rng=0)[0].image
    nearest = nearest_edge_field(observe_edges(image))
    assert calibrate_palm_scale(model, geometry, q, cam, nearest) == pytest.approx(1.0, abs=0.03)
    T_true = palm_pose_from_state(model, q)
    T_start = T_true.copy()
    T_start[:3, :3] = matrix_from_quaternion(quaternion_from_rotvec(
        np.array([0.02, -0.015, 0.02]))) @ T_true[:3, :3]
    T_start[:3, 3] += (2.0, -2.0, 3.0)
    q_start = with_palm_pose(model, q, T_start)
    visible = outline_visibility(model, geometry, q_start, cam, palm_outline_points(geometry))
    fit = icp_palm(model, geometry, q_start, cam, nearest, visible=visible)
    assert fit.rms_px < 1.5
    # The outline alone pins the tilt of the palm only weakly (measured: about 5 degrees
    # off from a 2-degree, 4-mm perturbed start; see docs/divide-and-conquer.md).
    assert _angle_deg(fit.T_world_palm[:3, :3], T_true[:3, :3]) < 6.5
    assert np.linalg.norm(fit.T_world_palm[:3, 3] - T_true[:3, 3]) < 8.0


def test_nearest_edges_agree_with_the_exact_distance_transform():
    """The k-d tree's nearest edge pixel is at the exact Euclidean distance that scipy's
    distance transform gives, for every pixel of a random edge map; a map without edges
    answers inf."""
    from scipy.ndimage import distance_transform_edt

    rng = np.random.default_rng(0)
    edges = (rng.random((60, 80)) < 0.01).astype(np.uint8) * 255
    rows, cols = np.indices(edges.shape).reshape(2, -1)
    dist, pixel = nearest_edge_field(edges).at(rows, cols)
    np.testing.assert_allclose(dist, distance_transform_edt(edges == 0).ravel(), atol=1e-9)
    assert (edges[pixel[:, 0], pixel[:, 1]] == 255).all()
    np.testing.assert_allclose(np.hypot(pixel[:, 0] - rows, pixel[:, 1] - cols), dist)
    empty, _ = nearest_edge_field(np.zeros((5, 5), np.uint8)).at(np.array([2]), np.array([2]))
    assert np.isinf(empty).all()


def test_nearest_edges_list_the_edge_pixels_in_row_major_order():
    """The edge pixels are those of ``np.argwhere`` in its order (row-major), so that the
    k-d tree, and with it every tie between equally near edge pixels, is the same; any
    non-zero value is an edge."""
    rng = np.random.default_rng(1)
    edges = (rng.random((48, 64)) < 0.05) * rng.integers(1, 256, (48, 64))
    for edge_map in (edges.astype(np.uint8), edges.astype(np.float32)):
        np.testing.assert_array_equal(nearest_edge_field(edge_map).edges,
                                      np.argwhere(edge_map != 0))


def _outline_edge_map(model, geometry, q, camera, corners):
    """An edge map (255 on edges) with the outline ``corners`` (4, 3) drawn at state ``q``."""
    import cv2

    from digiteyes.kinematics import forward_kinematics
    T = forward_kinematics(model, q[None]).T_world_shape[0, geometry.palm_row]
    uv = camera.project(corners @ T[:3, :3].T + T[:3, 3])
    edges = np.zeros((camera.height, camera.width), np.uint8)
    cv2.polylines(edges, [np.rint(uv).astype(np.int32)], True, 255, 1)
    return edges


def test_outline_calibration_recovers_moved_sides(natural_cardboard):
    """Edges drawn from an outline whose radial side is 9 mm further out and whose wrist
    side is 6 mm further in: the calibration finds both (to the 1 mm grid, within a
    pixel's worth), leaves the ulnar side and the unfitted distal side in place."""
    from digiteyes.smc.likelihood import edge_lookup
    from digiteyes.smc.palm import calibrate_palm_outline
    model, cam, states = natural_cardboard
    geometry = FingerGeometry.of(model)
    c = geometry.palm_outline.copy()                     # sides: 0 wrist (y min), 1 radial
    moved = c.copy()                                     # (x max), 2 distal, 3 ulnar
    moved[[1, 2], 0] += 9.0
    moved[[0, 1], 1] += 6.0
    edges = _outline_edge_map(model, geometry, states[0], cam, moved)
    fit = calibrate_palm_outline(model, geometry, states[0], cam, edge_lookup(edges))
    assert abs(fit.offsets_mm[1] - 9.0) <= 1.5 and abs(fit.offsets_mm[0] + 6.0) <= 1.5
    assert fit.offsets_mm[3] == 0.0 and fit.offsets_mm[2] == 0.0 and np.isnan(fit.scores[2])
    np.testing.assert_allclose(fit.corners[2], [c[2, 0] + fit.offsets_mm[1], c[2, 1], 0.0])
    # the model's own outline: nothing moves
    same = calibrate_palm_outline(model, geometry, states[0], cam,
                                  edge_lookup(_outline_edge_map(model, geometry, states[0],
                                                                cam, c)))
    np.testing.assert_array_equal(same.offsets_mm, 0.0)
    np.testing.assert_array_equal(same.corners, c)
