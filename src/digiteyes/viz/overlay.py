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


def to_rgb(image: np.ndarray) -> np.ndarray:
    """``image`` as (H, W, 3) RGB uint8: grey is repeated, floats up to 1.0 are scaled."""
    image = np.asarray(image)
    if image.ndim == 3 and image.shape[2] == 1:
        image = image[..., 0]
    if image.dtype != np.uint8:
        scale = 255.0 if np.issubdtype(image.dtype, np.floating) and image.max() <= 1.0 else 1.0
        image = np.clip(image * scale, 0, 255).astype(np.uint8)
    if image.ndim == 2:
        return cv2.cvtColor(np.ascontiguousarray(image), cv2.COLOR_GRAY2RGB)
    if image.ndim == 3 and image.shape[2] in (3, 4):
        return np.ascontiguousarray(image[..., :3])
    raise CameraError(f"images must be (H, W) grey or (H, W, 3) RGB, got shape {image.shape}")


class _Canvas:
    """An RGB image scaled by an integer factor, drawn on in original pixel coordinates.

    Points come in arrays ``(..., 2)`` px; entries with a non-finite coordinate are
    skipped. All segments of one colour go to OpenCV in one call."""

    def __init__(self, rgb: np.ndarray, scale: int) -> None:
        if scale > 1:
            rgb = cv2.resize(rgb, None, fx=scale, fy=scale, interpolation=cv2.INTER_NEAREST)
        self.image = np.ascontiguousarray(rgb)
        self.scale = scale

    def _fixed(self, p: np.ndarray) -> np.ndarray:
        """(N, 2) int32 fixed-point (``SHIFT`` fraction bits) canvas coordinates."""
        return np.rint(((p + 0.5) * self.scale - 0.5) * _ONE).astype(np.int32)

    def lines(self, a, b, color, thickness: int = 1) -> None:
        """Segments from ``a`` to ``b`` (same shapes, (..., 2))."""
        a = np.asarray(a, dtype=float).reshape(-1, 2)
        b = np.asarray(b, dtype=float).reshape(-1, 2)
        ok = np.isfinite(a).all(axis=1) & np.isfinite(b).all(axis=1)
        if ok.any():
            ends = np.stack([self._fixed(a[ok]), self._fixed(b[ok])], axis=1)
            cv2.polylines(self.image, list(ends), False, color, thickness, cv2.LINE_AA, SHIFT)

    def dots(self, p, color, radius_px: float = 1.5) -> None:
        p = np.asarray(p, dtype=float).reshape(-1, 2)
        radius = max(round(radius_px * self.scale * _ONE), _ONE)
        for x, y in self._fixed(p[np.isfinite(p).all(axis=1)]).tolist():
            cv2.circle(self.image, (x, y), radius, color, -1, cv2.LINE_AA, SHIFT)

    def crosses(self, p, color, size_px: float = 3.0) -> None:
        p = np.asarray(p, dtype=float).reshape(-1, 2)
        for d in (np.array([1.0, 1.0]), np.array([1.0, -1.0])):
            self.lines(p - size_px * d, p + size_px * d, color, 1)

    def text(self, p, label: str, color) -> None:
        x, y = self._fixed(np.asarray(p, dtype=float).reshape(1, 2))[0]
        cv2.putText(self.image, label, (int(x) >> SHIFT, int(y) >> SHIFT),
                    cv2.FONT_HERSHEY_SIMPLEX, 0.35 * max(self.scale, 1), color, 1, cv2.LINE_AA)


def _foot(line: np.ndarray, p: np.ndarray) -> np.ndarray:
    """Closest points of the lines ``(a, b, rho)`` (N, 3) to the points ``p`` (N, 2)."""
    n = line[:, :2]
    return p - (np.sum(n * p, axis=1) - line[:, 2])[:, None] * n


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
    (H * scale, W * scale, 3) RGB uint8 image. Layers, bottom to top: slices, trackers,
    edge points, measured features, residuals.
    """
    rgb = to_rgb(image)
    if camera is not None and rgb.shape[:2] != (camera.height, camera.width):
        raise CameraError(
            f"camera {camera.name!r} expects {camera.width}x{camera.height} images, got "
            f"{rgb.shape[1]}x{rgb.shape[0]}"
        )
    if int(scale) != scale or scale < 1:
        raise ValueError(f"scale must be a positive integer, got {scale!r}")
    canvas = _Canvas(rgb, int(scale))
    valid = np.asarray(meas.link_valid, dtype=bool)
    tip_valid = np.asarray(meas.tip_valid, dtype=bool)

    if show_slices:
        for ends in (meas.slice_ends, meas.tip_slice_ends):
            canvas.lines(ends[..., 0, :], ends[..., 1, :], SLICE)

    # T trackers: the predicted axis with a crossbar at the link end a little wider than
    # the predicted contour at the last slice; carets at the predicted tips.
    start, end = meas.predicted_axis[:, 0], meas.predicted_axis[:, 1]
    last = np.abs(meas.contour_offsets[:, -1:, :]).reshape(len(start), -1)  # none: exact
    widest = np.where(np.isfinite(last), last, -np.inf).max(axis=1, initial=-np.inf)
    half_width = np.where(np.isfinite(widest), widest, DEFAULT_HALF_WIDTH)
    bar = meas.slice_normal * (half_width + 2.0)[:, None]
    c, u = meas.predicted_tip, meas.tip_direction
    n = np.stack([-u[:, 1], u[:, 0]], axis=1)
    for colour, links, tips in ((TRACKER, valid, tip_valid), (INVALID, ~valid, ~tip_valid)):
        canvas.lines(start[links], end[links], colour, 2)
        canvas.lines(end[links] - bar[links], end[links] + bar[links], colour, 2)
        for side in (1.0, -1.0):
            canvas.lines(c[tips], c[tips] - 4.0 * u[tips] + side * 3.0 * n[tips], colour, 2)

    inlier = np.asarray(meas.edge_inlier, dtype=bool)
    canvas.dots(meas.edge_points[inlier], EDGE_IN)
    canvas.dots(meas.edge_points[~inlier], EDGE_OUT)
    canvas.dots(meas.tip_edge_points, EDGE_IN)

    line = meas.line[valid]
    canvas.lines(_foot(line, start[valid]), _foot(line, end[valid]), MEASURED, 1)
    canvas.crosses(meas.measured_tip[tip_valid], MEASURED)

    if residual_layout is None:
        for p in (start[valid], end[valid]):
            canvas.lines(p, _foot(line, p), RESIDUAL, 2)
        canvas.lines(c[tip_valid], meas.measured_tip[tip_valid], RESIDUAL, 2)
    elif residual_layout.camera == meas.camera:
        kind = residual_layout.kind
        links = kind == "link"
        p, f = residual_layout.points_px[links], residual_layout.feature[links]
        canvas.lines(p, _foot(meas.line[f], p), RESIDUAL, 2)
        tips = (kind == "tip") & (residual_layout.component == 0)
        canvas.lines(residual_layout.points_px[tips],
                     meas.measured_tip[residual_layout.feature[tips]], RESIDUAL, 2)
    if camera is not None:
        canvas.text(np.array([4.0, 12.0]), camera.name, TRACKER)
    return canvas.image
