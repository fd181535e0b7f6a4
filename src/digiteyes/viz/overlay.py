"""Overlays of feature measurements on images (report Fig. 4, thesis Fig. 4.2).

:func:`draw_features` draws, for every tracked link, the T-shaped tracker (the projected
model axis with a crossbar at the link end), its slices, the detected edge points (kept or
rejected by the robust fit), the measured axis line and the residuals (slashed lines from
the model axis to the measured line); for every tip the caret of the predicted tip, the
tip slices, the measured tip (a cross) and the residual vector. Colours are RGB.
"""

from __future__ import annotations

import cv2
import numpy as np

from digiteyes.camera import Camera
from digiteyes.errors import CameraError
from digiteyes.features.measure import FeatureMeasurement
from digiteyes.features.residuals import ResidualLayout

TRACKER = (0, 200, 255)
INVALID = (150, 60, 60)
SLICE = (110, 110, 30)
EDGE_IN = (40, 255, 40)
EDGE_OUT = (255, 70, 70)
MEASURED = (255, 0, 255)
RESIDUAL = (255, 40, 40)
DEFAULT_HALF_WIDTH = 6.0  # crossbar half-length without slices (e.g. exact features), px
SHIFT = 4
_ONE = 1 << SHIFT


def _to_rgb(image: np.ndarray) -> np.ndarray:
    image = np.asarray(image)
    if image.ndim == 3 and image.shape[2] == 1:
        image = image[..., 0]
    if image.dtype != np.uint8:
        scale = 255.0 if np.issubdtype(image.dtype, np.floating) and image.max() <= 1.0 else 1.0
        image = np.clip(image * scale, 0, 255).astype(np.uint8)
    if image.ndim == 2:
        return np.repeat(image[..., None], 3, axis=2)
    if image.ndim == 3 and image.shape[2] in (3, 4):
        return np.ascontiguousarray(image[..., :3])
    raise CameraError(f"images must be (H, W) grey or (H, W, 3) RGB, got shape {image.shape}")


class _Canvas:
    """An RGB image scaled by an integer factor, drawn on in original pixel coordinates."""

    def __init__(self, rgb: np.ndarray, scale: int) -> None:
        if scale > 1:
            rgb = cv2.resize(rgb, None, fx=scale, fy=scale, interpolation=cv2.INTER_NEAREST)
        self.image = np.ascontiguousarray(rgb)
        self.scale = scale

    def _pt(self, p: np.ndarray) -> tuple[int, int]:
        q = ((np.asarray(p, dtype=float) + 0.5) * self.scale - 0.5) * _ONE
        return round(float(q[0])), round(float(q[1]))

    def line(self, a, b, color, thickness: int = 1) -> None:
        if np.isfinite(a).all() and np.isfinite(b).all():
            cv2.line(self.image, self._pt(a), self._pt(b), color, thickness, cv2.LINE_AA, SHIFT)

    def dot(self, p, color, radius_px: float = 1.5) -> None:
        if np.isfinite(p).all():
            radius = max(round(radius_px * self.scale * _ONE), _ONE)
            cv2.circle(self.image, self._pt(p), radius, color, -1, cv2.LINE_AA, SHIFT)

    def cross(self, p, color, size_px: float = 3.0) -> None:
        for d in (np.array([1.0, 1.0]), np.array([1.0, -1.0])):
            self.line(p - size_px * d, p + size_px * d, color, 1)

    def text(self, p, label: str, color) -> None:
        x, y = self._pt(p)
        cv2.putText(self.image, label, (x >> SHIFT, y >> SHIFT), cv2.FONT_HERSHEY_SIMPLEX,
                    0.35 * max(self.scale, 1), color, 1, cv2.LINE_AA)


def _foot(line: np.ndarray, p: np.ndarray) -> np.ndarray:
    """Closest point of the line ``(a, b, rho)`` to ``p``."""
    return p - (line[:2] @ p - line[2]) * line[:2]


def draw_features(
    image: np.ndarray,
    meas: FeatureMeasurement,
    camera: Camera | None = None,
    residual_layout: ResidualLayout | None = None,
    *,
    scale: int = 1,
    show_slices: bool = True,
) -> np.ndarray:
    """Draw trackers, slices, edges, measured features and residuals on an image.

    Parameters
    ----------
    image : (H, W) grey or (H, W, 3) RGB, uint8 or float (floats up to 1.0 are taken as
        0..1, others as 0..255).
    meas : the measurement made in this image.
    camera : if given, the image size is checked against it and its name is written in
        the top-left corner.
    residual_layout : if given (from :func:`~digiteyes.features.feature_residuals`), the
        residuals are drawn from the model points it lists (the state the residuals were
        evaluated at, e.g. after the solver); otherwise from the predicted axis ends and
        tips that placed the trackers.
    scale : integer magnification of the output (finer lines on small features).
    show_slices : draw the slices (search ranges).

    Returns
    -------
    (H * scale, W * scale, 3) RGB uint8 image.
    """
    rgb = _to_rgb(image)
    if camera is not None and rgb.shape[:2] != (camera.height, camera.width):
        raise CameraError(
            f"camera {camera.name!r} expects {camera.width}x{camera.height} images, got "
            f"{rgb.shape[1]}x{rgb.shape[0]}"
        )
    if int(scale) != scale or scale < 1:
        raise ValueError(f"scale must be a positive integer, got {scale!r}")
    canvas = _Canvas(rgb, int(scale))

    for k in range(len(meas.link_ids)):
        valid = bool(meas.link_valid[k])
        if show_slices:
            for a, b in meas.slice_ends[k]:
                canvas.line(a, b, SLICE)
        start, end = meas.predicted_axis[k]
        colour = TRACKER if valid else INVALID
        canvas.line(start, end, colour, 2)
        last = meas.contour_offsets[k, -1:].ravel()  # predicted contour at the last slice
        half_width = np.abs(last).max() if np.isfinite(last).any() else DEFAULT_HALF_WIDTH
        bar = meas.slice_normal[k] * (half_width + 2.0)
        canvas.line(end - bar, end + bar, colour, 2)
        for side in range(2):
            for p, kept in zip(meas.edge_points[k, side], meas.edge_inlier[k, side],
                               strict=True):
                canvas.dot(p, EDGE_IN if kept else EDGE_OUT)
        if valid:
            line = meas.line[k]
            canvas.line(_foot(line, start), _foot(line, end), MEASURED, 1)
            if residual_layout is None:
                for p in (start, end):
                    canvas.line(p, _foot(line, p), RESIDUAL, 2)

    for t in range(len(meas.tip_ids)):
        if show_slices:
            for a, b in meas.tip_slice_ends[t]:
                canvas.line(a, b, SLICE)
        for p in meas.tip_edge_points[t]:
            canvas.dot(p, EDGE_IN)
        c = meas.predicted_tip[t]
        u = meas.tip_direction[t]
        n = np.array([-u[1], u[0]])
        colour = TRACKER if meas.tip_valid[t] else INVALID
        canvas.line(c, c - 4.0 * u + 3.0 * n, colour, 2)
        canvas.line(c, c - 4.0 * u - 3.0 * n, colour, 2)
        if meas.tip_valid[t]:
            canvas.cross(meas.measured_tip[t], MEASURED)
            if residual_layout is None:
                canvas.line(c, meas.measured_tip[t], RESIDUAL, 2)

    if residual_layout is not None and residual_layout.camera == meas.camera:
        for row in range(residual_layout.n_rows):
            p = residual_layout.points_px[row]
            f = residual_layout.feature[row]
            if residual_layout.kind[row] == "link":
                canvas.line(p, _foot(meas.line[f], p), RESIDUAL, 2)
            elif residual_layout.kind[row] == "tip" and residual_layout.component[row] == 0:
                canvas.line(p, meas.measured_tip[f], RESIDUAL, 2)
    if camera is not None:
        canvas.text(np.array([4.0, 12.0]), camera.name, TRACKER)
    return canvas.image
