"""Palm pose (Huang Sec. 4): ICP against image edges, pose from correspondences by
factorisation under scaled orthography, then refinement under the perspective camera.

The palm is a rigid plane. Its model points ``x_i`` (mm, in the plane of the palm's shape
frame) are sampled along the palm outline; their images ``m_i`` are the nearest edge pixels
(ICP, Sec. 4.1). In normalised image coordinates (pixels through ``K^-1``, undistorted) the
scaled orthographic camera gives ``t3 m_i = A x_i + t`` with ``A`` the upper-left 2x2 block
of the rotation (Sec. 4.2). Subtracting centroids, ``W = B S`` with ``B = A / t3``: the
factorisation ``W = M S`` of Tomasi and Kanade with the shape ``S`` known from calibration,
so ``M = B = W S^+`` by least squares. The metric constraint (the first two columns of a
rotation are orthonormal 3-vectors) fixes ``t3`` and the missing third row of those
columns, up to the planar sign ambiguity; then ``t1, t2 = t3 m_bar - A x_bar``. The result
seeds OpenCV's Levenberg-Marquardt reprojection refinement (``cv2.solvePnP``, iterative)
under the full perspective camera, distortion included.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np
from scipy.spatial import cKDTree

from digiteyes.camera import Camera
from digiteyes.errors import DigitEyesError
from digiteyes.kinematics import KinematicModel, forward_kinematics
from digiteyes.kinematics.rotations import matrix_from_quaternion, quaternion_from_matrix
from digiteyes.smc.likelihood import EdgeLookup, FingerGeometry


class PalmPoseError(DigitEyesError, ValueError):
    """Too few or degenerate palm correspondences."""


def planar_pose_candidates(x_model: np.ndarray, m_norm: np.ndarray
                           ) -> list[tuple[np.ndarray, np.ndarray]]:
    """Poses ``(R_cam_plane, t_cam_plane)`` of a plane from correspondences under scaled
    orthography (Huang Sec. 4.2).

    ``x_model`` (N, 2) plane points (mm, plane z = 0), ``m_norm`` (N, 2) their images in
    normalised coordinates. Returns the two solutions of the planar sign ambiguity (one if
    the plane is seen exactly face-on). Raises :class:`PalmPoseError` for fewer than 3
    points or collinear ones.
    """
    x_model, m_norm = np.asarray(x_model, dtype=float), np.asarray(m_norm, dtype=float)
    if len(x_model) < 3 or x_model.shape != m_norm.shape:
        raise PalmPoseError(f"need at least 3 palm correspondences (N, 2), got "
                            f"{x_model.shape} and {m_norm.shape}")
    x_bar, m_bar = x_model.mean(axis=0), m_norm.mean(axis=0)
    S = (x_model - x_bar).T                       # 2 x N shape
    W = (m_norm - m_bar).T                        # 2 x N measurements
    SS = S @ S.T
    if np.linalg.cond(SS) > 1e8:
        raise PalmPoseError("palm model points are collinear")
    B = W @ S.T @ np.linalg.inv(SS)               # M = W S^+ (factorisation, S known)
    a, c, b = B[:, 0] @ B[:, 0], B[:, 1] @ B[:, 1], B[:, 0] @ B[:, 1]
    # Metric constraint on the columns of A = t3 B, k = t3^2:
    # (1 - k a)(1 - k c) = k^2 b^2, the smaller root is the valid one.
    det = a * c - b * b
    if abs(det) < 1e-18:
        k = 1.0 / (a + c)
    else:
        disc = max((a + c) ** 2 - 4.0 * det, 0.0)
        k = ((a + c) - np.sqrt(disc)) / (2.0 * det)
    A = np.sqrt(k) * B
    r31sq, r32sq = max(1.0 - k * a, 0.0), max(1.0 - k * c, 0.0)
    if r31sq > r32sq:
        r31 = np.sqrt(r31sq)
        r32 = -k * b / r31
    else:
        r32 = np.sqrt(r32sq)
        r31 = -k * b / r32 if r32 > 0 else 0.0
    out = []
    for sign in ((1.0, -1.0) if max(r31sq, r32sq) > 1e-12 else (1.0,)):
        r1 = np.array([A[0, 0], A[1, 0], sign * r31])
        r2 = np.array([A[0, 1], A[1, 1], sign * r32])
        U, _, Vt = np.linalg.svd(np.stack([r1, r2, np.cross(r1, r2)], axis=1))
        R = U @ Vt
        if np.linalg.det(R) < 0:
            R = U @ np.diag([1.0, 1.0, -1.0]) @ Vt
        t3 = np.sqrt(k)
        t12 = t3 * m_bar - A @ x_bar
        out.append((R, np.array([t12[0], t12[1], t3])))
    return out


def _normalised(camera: Camera, pixels: np.ndarray) -> np.ndarray:
    if camera.projection == "perspective":
        return cv2.undistortPoints(pixels.reshape(-1, 1, 2).astype(np.float64),
                                   np.asarray(camera.K), np.asarray(camera.dist)).reshape(-1, 2)
    Kinv = np.linalg.inv(np.asarray(camera.K))
    return pixels @ Kinv[:2, :2].T + Kinv[:2, 2]


def palm_pose_from_correspondences(camera: Camera, x_model: np.ndarray, pixels: np.ndarray,
                                   R_hint: np.ndarray | None = None, refine: bool = True
                                   ) -> tuple[np.ndarray, float]:
    """``T_cam_plane`` (4, 4) of the palm plane from plane points (N, 2) mm and their pixels
    (N, 2): factorisation (Huang Sec. 4.2), then perspective refinement. Of the two planar
    solutions the one nearer ``R_hint`` (or with the smaller reprojection error) is kept.
    Returns the pose and the RMS reprojection error, px."""
    pixels = np.asarray(pixels, dtype=float)
    candidates = planar_pose_candidates(x_model, _normalised(camera, pixels))
    obj = np.concatenate([x_model, np.zeros((len(x_model), 1))], axis=1)
    best, best_key, best_rms = np.eye(4), np.inf, np.nan
    for R, t in candidates:
        T = np.eye(4)
        T[:3, :3], T[:3, 3] = R, t
        if refine and camera.projection == "perspective":
            rvec, _ = cv2.Rodrigues(R)
            ok, rvec, tvec = cv2.solvePnP(obj, pixels, np.asarray(camera.K),
                                          np.asarray(camera.dist), rvec, t.reshape(3, 1),
                                          useExtrinsicGuess=True, flags=cv2.SOLVEPNP_ITERATIVE)
            if ok:
                T[:3, :3], T[:3, 3] = cv2.Rodrigues(rvec)[0], tvec.ravel()
        w = _project_plane(camera, T, obj)
        rms = float(np.sqrt(np.mean(np.sum((w - pixels) ** 2, axis=1))))
        key = rms if R_hint is None else np.linalg.norm(T[:3, :3] - R_hint)
        if key < best_key:
            best, best_key, best_rms = T, key, rms
    return best, best_rms


def _project_plane(camera: Camera, T_cam_plane: np.ndarray, obj: np.ndarray) -> np.ndarray:
    p_world = (camera.T_world_cam @ T_cam_plane @ np.c_[obj, np.ones(len(obj))].T)[:3].T
    return camera.project(p_world)


@dataclass(frozen=True)
class IcpOptions:
    """points_per_side : outline samples per palm side; sides : which of the outline's
    sides are used (0 wrist, 1 radial, 2 distal, 3 ulnar; the distal side is where the
    fingers join and has no edge of its own); max_distance_px : correspondences farther
    than this are dropped; iterations : ICP rounds (Huang Sec. 4.1)."""

    points_per_side: int = 12
    sides: tuple[int, ...] = (0, 1, 3)
    max_distance_px: float = 12.0
    iterations: int = 4


def palm_outline_points(geometry: FingerGeometry, options: IcpOptions = IcpOptions(),
                        scale: float = 1.0) -> np.ndarray:
    """Model points (P, 3) on the palm outline in the palm shape frame, mm, the outline
    scaled by ``scale`` about its centre (palm-size calibration)."""
    corners = geometry.palm_outline
    centre = corners.mean(axis=0)
    corners = centre + scale * (corners - centre)
    t = (np.arange(options.points_per_side) + 0.5) / options.points_per_side
    pts = [corners[s] + t[:, None] * (corners[(s + 1) % 4] - corners[s]) for s in options.sides]
    return np.concatenate(pts)


@dataclass(frozen=True)
class NearestEdges:
    """Nearest-edge queries on one edge map: a k-d tree of its edge pixels.

    The ICP asks for the nearest edge of a few dozen outline points per iteration; a tree
    of the edge pixels answers that exactly (the Euclidean distance transform of the whole
    frame did the same in 11 ms at 640x480, the tree takes about 1 ms to build).
    ``shape`` (H, W) of the map; ``edges`` (E, 2) int row, col of its edge pixels.
    """

    shape: tuple[int, int]
    edges: np.ndarray
    tree: cKDTree | None

    def at(self, rows: np.ndarray, cols: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Distance (P,) px from pixels (``rows``, ``cols``) (P,) to their nearest edge
        pixel and its (row, col) (P, 2); ``inf`` and (-1, -1) on a map without edges."""
        points = np.stack([rows, cols], axis=1).astype(float)
        if self.tree is None:
            return np.full(len(points), np.inf), np.full((len(points), 2), -1)
        dist, k = self.tree.query(points)
        return dist, self.edges[k]


def nearest_edge_field(edge_map: np.ndarray) -> NearestEdges:
    """The :class:`NearestEdges` of an edge map (H, W) (non-zero on edges)."""
    found = cv2.findNonZero((np.asarray(edge_map) != 0).view(np.uint8))
    # OpenCV lists (x, y) in row-major order, as np.argwhere lists (row, col): same rows
    edges = np.zeros((0, 2), dtype=np.int64) if found is None else \
        found.reshape(-1, 2)[:, ::-1].astype(np.int64)
    return NearestEdges(edge_map.shape[:2], edges, cKDTree(edges) if len(edges) else None)


@dataclass(frozen=True)
class PalmFit:
    """ICP result: ``T_world_palm`` (4, 4), model points used (P, 3) palm frame, their
    matched pixels (P, 2), ``rms_px`` reprojection error and ``iterations``."""

    T_world_palm: np.ndarray
    model_points: np.ndarray
    pixels: np.ndarray
    rms_px: float
    iterations: int


def palm_pose_from_state(model: KinematicModel, q: np.ndarray) -> np.ndarray:
    """``T_world_palm`` (4, 4) of the root pose states (unit quaternion w, x, y, z; mm)."""
    T = np.eye(4)
    i = model.base_state
    T[:3, :3] = matrix_from_quaternion(q[i:i + 4] / np.linalg.norm(q[i:i + 4]))
    T[:3, 3] = q[i + 4:i + 7]
    return T


def with_palm_pose(model: KinematicModel, q: np.ndarray, T_world_palm: np.ndarray
                   ) -> np.ndarray:
    """Copy of ``q`` with its root pose states set from ``T_world_palm``."""
    q = np.array(q, dtype=float)
    i = model.base_state
    quat = quaternion_from_matrix(T_world_palm[:3, :3])
    if quat @ q[i:i + 4] < 0:
        quat = -quat
    q[i:i + 4], q[i + 4:i + 7] = quat, T_world_palm[:3, 3]
    return q


def icp_palm(model: KinematicModel, geometry: FingerGeometry, q: np.ndarray, camera: Camera,
             nearest: NearestEdges, options: IcpOptions = IcpOptions(),
             scale: float = 1.0, visible: np.ndarray | None = None) -> PalmFit:
    """ICP of the palm outline against the edge map (Huang Sec. 4.1-4.2), from state ``q``.

    ``nearest`` is :func:`nearest_edge_field` of the frame; ``visible`` (P,) optionally
    masks outline points hidden by fingers. Raises :class:`PalmPoseError` when fewer than
    6 correspondences are left.
    """
    pts = palm_outline_points(geometry, options, scale)
    mask = np.ones(len(pts), bool) if visible is None else np.asarray(visible, bool)
    plane_z = pts[0, 2]
    x_model = pts[:, :2]
    T_world_palm = palm_pose_from_state(model, q)
    h, w = nearest.shape
    pixels = np.zeros((len(pts), 2))
    rms, it = np.nan, 0
    for it in range(1, options.iterations + 1):
        p_world = (T_world_palm[:3, :3] @ pts.T).T + T_world_palm[:3, 3]
        uv = camera.project(p_world)
        inside = mask & np.isfinite(uv).all(axis=1)
        inside &= (uv[:, 0] >= 0) & (uv[:, 0] <= w - 1) & (uv[:, 1] >= 0) & (uv[:, 1] <= h - 1)
        col = np.clip(np.rint(uv[:, 0]), 0, w - 1).astype(int)
        row = np.clip(np.rint(uv[:, 1]), 0, h - 1).astype(int)
        pixels = nearest.at(row, col)[1][:, ::-1].astype(float)
        gap = np.linalg.norm(pixels - uv, axis=1)
        limit = max(options.max_distance_px / it, 3.0 * np.median(gap[inside]), 2.0) \
            if inside.any() else 0.0
        close = inside & (gap <= min(limit, options.max_distance_px))
        if close.sum() < 6:
            raise PalmPoseError(f"only {int(close.sum())} palm outline points found an edge "
                                f"within {options.max_distance_px} px")
        T_shift = np.eye(4)
        T_shift[2, 3] = plane_z
        R_hint = (camera.T_cam_world @ T_world_palm)[:3, :3]
        T_cam_plane, rms = palm_pose_from_correspondences(camera, x_model[close],
                                                          pixels[close], R_hint)
        T_new = camera.T_world_cam @ T_cam_plane @ np.linalg.inv(T_shift)
        moved = np.linalg.norm(T_new[:3, 3] - T_world_palm[:3, 3])
        T_world_palm = T_new
        if moved < 0.2:
            break
    return PalmFit(T_world_palm, pts[close], pixels[close], rms, it)


def outline_visibility(model: KinematicModel, geometry: FingerGeometry, q: np.ndarray,
                       camera: Camera, points: np.ndarray, margin_mm: float = 3.0
                       ) -> np.ndarray:
    """(P,) whether each palm outline point (palm shape frame, mm) is not covered by a
    finger patch nearer the camera (the occlusion map of Huang Sec. 5.2, for the palm)."""
    shapes = forward_kinematics(model, q).T_world_shape[0]
    T = shapes[geometry.link_rows]
    starts = T[:, :3, 3]
    ends = starts + T[:, :3, 0] * geometry.lengths[:, None]
    P = shapes[geometry.palm_row]
    p_world = (P[:3, :3] @ points.T).T + P[:3, 3]
    uv, z = camera.project(p_world), camera.depth(p_world)
    a, b = camera.project(starts), camera.project(ends)
    za, zb = camera.depth(starts), camera.depth(ends)
    e = b - a
    tau = np.clip(np.einsum("pld,ld->pl", uv[:, None] - a[None], e)
                  / np.maximum(np.einsum("ld,ld->l", e, e), 1e-12), 0.0, 1.0)
    gap = np.linalg.norm(a[None] + tau[..., None] * e[None] - uv[:, None], axis=2)
    depth = za[None] + tau * (zb - za)[None]
    radius_px = geometry.radii[None] * camera.K[0, 0] / (
        depth if camera.projection == "perspective" else camera.depth_mm)
    hidden = (gap < radius_px) & (depth < z[:, None] - margin_mm)
    return ~hidden.any(axis=1)


def calibrate_palm_scale(model: KinematicModel, geometry: FingerGeometry, q: np.ndarray,
                         camera: Camera, nearest: NearestEdges,
                         scales: np.ndarray = np.linspace(0.8, 1.25, 19),  # noqa: B008
                         options: IcpOptions = IcpOptions()) -> float:
    """Palm size from a frame of the open palm at a known pose ``q`` (Huang Sec. 4.2, last
    paragraph): the outline scale whose projection lies closest to the edges (mean
    distance-transform value, truncated at ``max_distance_px``)."""
    h, w = nearest.shape
    T = palm_pose_from_state(model, q)
    costs = []
    for s in scales:
        pts = palm_outline_points(geometry, options, float(s))
        uv = camera.project((T[:3, :3] @ pts.T).T + T[:3, 3])
        col = np.clip(np.rint(uv[:, 0]), 0, w - 1).astype(int)
        row = np.clip(np.rint(uv[:, 1]), 0, h - 1).astype(int)
        costs.append(np.minimum(nearest.at(row, col)[0], options.max_distance_px).mean())
    return float(scales[int(np.argmin(costs))])


@dataclass(frozen=True)
class OutlineCalibration:
    """The palm outline fitted to a user's palm on one frame (:func:`calibrate_palm_outline`).

    corners : (4, 3) the new outline corners, palm shape frame, mm (wrist-radial first, in
        the order of :attr:`FingerGeometry.palm_outline`).
    offsets_mm : (4,) how far each side (0 wrist, 1 radial, 2 distal, 3 ulnar) moved
        outwards (negative: inwards); sides not fitted, or without an edge, stay at 0.
    scores : (4,) the fitted sides' mean per-point edge score (:attr:`EdgeLookup.score`),
        NaN for sides not fitted.
    """

    corners: np.ndarray
    offsets_mm: np.ndarray
    scores: np.ndarray


def calibrate_palm_outline(model: KinematicModel, geometry: FingerGeometry, q: np.ndarray,
                           camera: Camera, lookup: EdgeLookup,
                           sides: tuple[int, ...] = (0, 1, 3),
                           offsets_mm: np.ndarray = np.arange(-10.0, 26.0, 1.0),  # noqa: B008
                           points_per_side: int = 12, min_score: float = 1.0,
                           min_offset_mm: float = 3.0) -> OutlineCalibration:
    """Fit the palm outline's sides to a frame at a known state ``q`` (n_q,): each of
    ``sides`` moves along its outward normal (in the palm plane) to the offset whose
    points lie best on the frame's edges (largest mean :attr:`EdgeLookup.score` of
    ``lookup``, Huang Sec. 5.2's per-point factor); a side whose best mean score is below
    ``min_score``, or whose best offset is within ``min_offset_mm`` of the model's (about
    a pixel at arm's length: not a measurable difference), keeps its place. The
    patch-size calibration of Huang Sec. 4.2 (last paragraph), per side: a user's palm is
    not the model's rectangle scaled (a fleshier palm reaches further towards the wrist
    and the thumb)."""
    corners = np.asarray(geometry.palm_outline, dtype=float)
    T = forward_kinematics(model, np.atleast_2d(q)).T_world_shape[0, geometry.palm_row]
    centre = corners.mean(axis=0)
    t = (np.arange(points_per_side) + 0.5) / points_per_side
    normals = np.zeros((4, 3))
    offsets, scores = np.zeros(4), np.full(4, np.nan)
    for side in range(4):
        a, b = corners[side], corners[(side + 1) % 4]
        along = (b - a) / np.linalg.norm(b - a)
        out = (a + b) / 2 - centre
        out -= along * (out @ along)
        normals[side] = out / np.linalg.norm(out)
        if side not in sides:
            continue
        base = a + t[:, None] * (b - a)                                    # (K, 3)
        shifted = base[None] + offsets_mm[:, None, None] * normals[side]   # (O, K, 3)
        uv = camera.project(shifted.reshape(-1, 3) @ T[:3, :3].T + T[:3, 3])
        score = lookup.at(uv)[0].reshape(len(offsets_mm), -1).mean(axis=1)
        k = int(np.argmax(score))
        scores[side] = score[k]
        if score[k] >= min_score and abs(offsets_mm[k]) >= min_offset_mm:
            offsets[side] = offsets_mm[k]
    # Corner k joins side k-1 and side k: it moves with both (the sides are perpendicular).
    moved = corners + offsets[:, None] * normals + np.roll(offsets, 1)[:, None] * np.roll(
        normals, 1, axis=0)
    return OutlineCalibration(moved, offsets, scores)
