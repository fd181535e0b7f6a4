"""Camera calibration from views of a chessboard or a ChArUco board (Zhang's method
through OpenCV), one camera or a stereo pair, and the rig it gives.

The board's corners lie in its own plane (z = 0) on a grid of ``square_mm``; OpenCV finds
them to sub-pixel precision, ``cv2.calibrateCamera`` estimates ``K`` and the distortion
``(k1, k2, p1, p2, k3)`` from several views, and ``cv2.stereoCalibrate`` the second
camera's pose relative to the first (the world frame of the rig is the first camera's
frame). A chessboard must be seen whole; a ChArUco board (a chessboard with ArUco markers
in its white squares) names each corner by the markers around it, so a view that shows
part of it still counts, and a stereo pair uses the corners both cameras saw.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import cv2
import numpy as np

from digiteyes.camera.camera import Camera
from digiteyes.camera.rig import Rig
from digiteyes.errors import CameraError


def board_points(pattern: tuple[int, int], square_mm: float) -> np.ndarray:
    """Inner-corner positions (cols * rows, 3) mm on the board plane, row by row, in
    OpenCV's corner order."""
    cols, rows = pattern
    grid = np.mgrid[0:cols, 0:rows].T.reshape(-1, 2)
    return np.column_stack([grid * square_mm, np.zeros(len(grid))]).astype(np.float32)


def find_chessboard(image: np.ndarray, pattern: tuple[int, int]) -> np.ndarray | None:
    """The inner corners (cols * rows, 2) px of a chessboard in an image (grey or RGB
    uint8), refined to sub-pixel precision, or None when the board is not found."""
    grey = image if image.ndim == 2 else cv2.cvtColor(image, cv2.COLOR_RGB2GRAY)
    found, corners = cv2.findChessboardCorners(
        grey, pattern, flags=cv2.CALIB_CB_ADAPTIVE_THRESH | cv2.CALIB_CB_NORMALIZE_IMAGE)
    if not found:
        return None
    criteria = (cv2.TERM_CRITERIA_EPS + cv2.TERM_CRITERIA_MAX_ITER, 40, 1e-3)
    corners = cv2.cornerSubPix(grey, corners, (5, 5), (-1, -1), criteria)
    return corners.reshape(-1, 2)


@dataclass(frozen=True)
class Chessboard:
    """A chessboard with ``pattern`` = (columns, rows) inner corners, squares of
    ``square_mm``."""

    pattern: tuple[int, int]
    square_mm: float

    def points(self) -> np.ndarray:
        """Corner positions (N, 3) mm on the board plane."""
        return board_points(self.pattern, self.square_mm)

    def detect(self, image: np.ndarray) -> tuple[np.ndarray, np.ndarray] | None:
        """Corner ids (N,) and pixels (N, 2) in ``image``, or None: all corners or none."""
        corners = find_chessboard(image, self.pattern)
        return None if corners is None else (np.arange(len(corners)), corners)

    def describe(self) -> str:
        return f"{self.pattern[0]}x{self.pattern[1]} chessboard"


@dataclass(frozen=True)
class CharucoBoard:
    """A ChArUco board of ``squares`` = (columns, rows) squares of ``square_mm``, ArUco
    markers of ``marker_mm`` from the OpenCV dictionary ``dictionary`` (as printed by
    ``cv2.aruco.CharucoBoard.generateImage``). Its inner corners are the calibration
    points; a view counts when at least :data:`MIN_CHARUCO_CORNERS` are found."""

    squares: tuple[int, int]
    square_mm: float
    marker_mm: float
    dictionary: str = "DICT_4X4_50"

    def __post_init__(self) -> None:
        if not 0 < self.marker_mm < self.square_mm:
            raise CameraError(f"ChArUco markers must be smaller than the squares, got "
                              f"{self.marker_mm} mm markers on {self.square_mm} mm squares")
        if not hasattr(cv2.aruco, self.dictionary):
            raise CameraError(f"unknown ArUco dictionary {self.dictionary!r} (e.g. "
                              "DICT_4X4_50, DICT_5X5_100, DICT_6X6_250)")

    def board(self) -> cv2.aruco.CharucoBoard:
        """The OpenCV board object."""
        words = cv2.aruco.getPredefinedDictionary(getattr(cv2.aruco, self.dictionary))
        return cv2.aruco.CharucoBoard(self.squares, self.square_mm, self.marker_mm, words)

    def points(self) -> np.ndarray:
        """Inner-corner positions (N, 3) mm on the board plane, by corner id."""
        return np.asarray(self.board().getChessboardCorners(), dtype=np.float32)

    def detect(self, image: np.ndarray) -> tuple[np.ndarray, np.ndarray] | None:
        """Ids (N,) and pixels (N, 2) of the inner corners found in ``image``, or None when
        fewer than :data:`MIN_CHARUCO_CORNERS`."""
        grey = image if image.ndim == 2 else cv2.cvtColor(image, cv2.COLOR_RGB2GRAY)
        corners, ids, _, _ = cv2.aruco.CharucoDetector(self.board()).detectBoard(grey)
        if ids is None or len(ids) < MIN_CHARUCO_CORNERS:
            return None
        return ids.ravel().astype(np.int64), np.asarray(corners, dtype=float).reshape(-1, 2)

    def describe(self) -> str:
        return f"{self.squares[0]}x{self.squares[1]} ChArUco board"


MIN_CHARUCO_CORNERS = 6
"""Fewest ChArUco corners for a view to count (a homography needs 4; 6 leave a margin)."""
Board = Chessboard | CharucoBoard


@dataclass
class Calibration:
    """A calibrated rig and how well it fits.

    Attributes
    ----------
    rig : one camera (world = camera frame) or two (world = the first camera's frame).
    rms_px : RMS reprojection error of the board corners, px (per camera, then stereo).
    views : board views used (per camera; pairs for stereo).
    """

    rig: Rig
    rms_px: dict[str, float]
    views: dict[str, int]


def calibrate(images: Sequence[np.ndarray], board: Board,
              second: Sequence[np.ndarray] | None = None, names: tuple[str, str] = ("cam0",
                                                                                    "cam1"),
              min_views: int = 3) -> Calibration:
    """Calibrate one camera from ``images`` of ``board`` or, with ``second`` (same length,
    taken at the same moments), a stereo pair.

    Raises :class:`CameraError` when fewer than ``min_views`` views (pairs) show the board.
    """
    if second is not None and len(second) != len(images):
        raise CameraError(f"stereo calibration needs as many images of the second camera as "
                          f"of the first, got {len(images)} and {len(second)}")
    obj = board.points()
    sets = [[board.detect(np.asarray(im)) for im in images]]
    if second is not None:
        sets.append([board.detect(np.asarray(im)) for im in second])
    cams, rms, views, per_cam = [], {}, {}, []
    for index, (frames, found) in enumerate(zip([images, second], sets, strict=False)):
        good = [c for c in found if c is not None]
        if len(good) < min_views:
            raise CameraError(f"camera {names[index]!r}: the {board.describe()} was found "
                              f"in {len(good)} of {len(found)} images; at least {min_views} "
                              "are needed")
        height, width = np.asarray(frames[0]).shape[:2]
        err, K, dist, _, _ = cv2.calibrateCamera([obj[ids] for ids, _ in good],
                                                 [px.astype(np.float32) for _, px in good],
                                                 (width, height), None, None)
        rms[names[index]] = float(err)
        views[names[index]] = len(good)
        per_cam.append((K, dist.ravel()[:5], width, height))
        cams.append(Camera.create(names[index], K, width, height, None, dist.ravel()[:5]))
    if second is None:
        return Calibration(Rig((cams[0],)), rms, views)
    both = [_common(a, b) for a, b in zip(*sets, strict=True)
            if a is not None and b is not None]
    both = [pair for pair in both if len(pair[0]) >= 4]
    if len(both) < min_views:
        raise CameraError(f"the {board.describe()} was seen by both cameras in {len(both)} "
                          f"image pairs; at least {min_views} are needed")
    (K0, d0, w, h), (K1, d1, _, _) = per_cam
    err, K0, d0, K1, d1, R, T, _, _ = cv2.stereoCalibrate(
        [obj[ids] for ids, _, _ in both], [a.astype(np.float32) for _, a, _ in both],
        [b.astype(np.float32) for _, _, b in both], K0, d0, K1, d1, (w, h),
        flags=cv2.CALIB_FIX_INTRINSIC)
    T_1_0 = np.eye(4)
    T_1_0[:3, :3], T_1_0[:3, 3] = R, np.ravel(T)
    rms["stereo"] = float(err)
    views["stereo"] = len(both)
    rig = Rig((cams[0], Camera.create(names[1], K1, cams[1].width, cams[1].height, T_1_0,
                                      np.ravel(d1)[:5])))
    return Calibration(rig, rms, views)


def _common(a: tuple[np.ndarray, np.ndarray], b: tuple[np.ndarray, np.ndarray]
            ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The corner ids both views found, and their pixels in each."""
    ids, ia, ib = np.intersect1d(a[0], b[0], return_indices=True)
    return ids, a[1][ia], b[1][ib]


def render_charuco(camera: Camera, T_cam_board: np.ndarray, board: CharucoBoard,
                   px_per_square: int = 60) -> np.ndarray:
    """A grey uint8 image of ``board`` seen by ``camera`` (its distortion ignored) from pose
    ``T_cam_board``, on a mid-grey background: for tests and demonstrations."""
    s, margin = px_per_square, px_per_square // 2
    cols, rows = board.squares
    texture = board.board().generateImage((cols * s + 2 * margin, rows * s + 2 * margin),
                                          marginSize=margin)
    # texture pixel centres -> board mm: board point x lies at pixel margin + x s / square - 1/2
    k = board.square_mm / s
    A = np.array([[k, 0.0, -(margin - 0.5) * k], [0.0, k, -(margin - 0.5) * k], [0, 0, 1]])
    R, t = T_cam_board[:3, :3], T_cam_board[:3, 3]
    H = camera.K @ np.column_stack([R[:, 0], R[:, 1], t]) @ A
    return cv2.warpPerspective(texture, H, (camera.width, camera.height),
                               flags=cv2.INTER_LINEAR, borderValue=128)


def render_chessboard(camera: Camera, T_cam_board: np.ndarray, pattern: tuple[int, int],
                      square_mm: float, px_per_square: int = 40) -> np.ndarray:
    """A grey uint8 image of a chessboard with ``pattern`` inner corners seen by ``camera``
    (its distortion ignored) from pose ``T_cam_board``, on a mid-grey background: for tests
    and demonstrations."""
    cols, rows = pattern
    s = px_per_square
    texture = np.full(((rows + 3) * s, (cols + 3) * s), 255, dtype=np.uint8)  # white margin
    for i in range(rows + 1):
        for j in range(cols + 1):
            if (i + j) % 2 == 0:
                texture[(i + 1) * s:(i + 2) * s, (j + 1) * s:(j + 2) * s] = 0
    # texture pixel centres -> board mm: the first inner corner is the pixel boundary at
    # 2 s - 0.5 in both axes
    k = square_mm / s
    A = np.array([[k, 0.0, -(2 * s - 0.5) * k], [0.0, k, -(2 * s - 0.5) * k], [0, 0, 1]])
    R, t = T_cam_board[:3, :3], T_cam_board[:3, 3]
    H = camera.K @ np.column_stack([R[:, 0], R[:, 1], t]) @ A
    image = cv2.warpPerspective(texture, H, (camera.width, camera.height),
                                flags=cv2.INTER_LINEAR, borderValue=128)
    return image
