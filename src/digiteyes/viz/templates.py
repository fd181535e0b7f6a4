"""Overlay of the layered template trackers (thesis Fig. 4.14): the window outlines of
the templates, the projected link axes, the segmentation as a tint, and the visibility
order written at each part (1 = front)."""

from __future__ import annotations

import cv2
import numpy as np

from digiteyes.occlusion.visibility import VisibilityOrder
from digiteyes.occlusion.windows import CAPSULE, ImageWindows
from digiteyes.viz.overlay import to_rgb

PALETTE = np.array([[230, 25, 75], [60, 180, 75], [255, 225, 25], [0, 130, 200],
                    [245, 130, 48], [145, 30, 180], [70, 240, 240], [240, 50, 230],
                    [210, 245, 60], [250, 190, 212], [0, 128, 128], [220, 190, 255],
                    [170, 110, 40], [255, 250, 200], [128, 0, 0], [170, 255, 195],
                    [128, 128, 0], [255, 215, 180], [0, 0, 128], [128, 128, 128]],
                   dtype=np.uint8)
"""RGB colours of the parts (cycled when there are more parts)."""


def _outline(windows: ImageWindows, k: int, samples: int = 48) -> np.ndarray:
    """Pixel polygon (N, 2) of window k's outline."""
    points = windows.points[k]
    if windows.kind[k] != CAPSULE:
        return points
    a, b, r = points[0], points[1], windows.radius[k]
    axis = b - a
    angle = np.arctan2(axis[1], axis[0]) if np.linalg.norm(axis) > 1e-9 else 0.0
    half = np.linspace(-np.pi / 2, np.pi / 2, samples // 2)
    cap_b = b + r * np.stack([np.cos(angle + half), np.sin(angle + half)], axis=1)
    cap_a = a + r * np.stack([np.cos(angle + np.pi + half), np.sin(angle + np.pi + half)],
                             axis=1)
    return np.concatenate([cap_b, cap_a])


def draw_templates(image: np.ndarray, windows: ImageWindows, order: VisibilityOrder,
                   segmentation: np.ndarray | None = None, names: list[str] | None = None,
                   tint: float = 0.35) -> np.ndarray:
    """Draw one camera's template overlay on a copy of ``image`` (grey or RGB).

    Parameters
    ----------
    image : the camera frame.
    windows : the parts' windows (``TemplateDetails.evaluations[c].windows``).
    order : the visibility order (``TemplateDetails.orders[c]``).
    segmentation : (H, W) part index per pixel, tinted in each part's colour if given.
    names : part names, written next to the rank when given.
    tint : opacity of the segmentation tint.

    Returns
    -------
    (H, W, 3) uint8 RGB image.
    """
    out = to_rgb(image).copy()
    colours = PALETTE[np.arange(len(windows.kind)) % len(PALETTE)]
    if segmentation is not None:
        mask = segmentation >= 0
        layer = colours[np.maximum(segmentation, 0)]
        out[mask] = ((1 - tint) * out[mask] + tint * layer[mask]).astype(np.uint8)
    rank = np.empty(len(order.order), dtype=int)
    rank[order.order] = np.arange(len(order.order))
    for k in order.order[::-1]:
        colour = tuple(int(c) for c in colours[k])
        outline = np.round(_outline(windows, k) * 4).astype(np.int32)
        cv2.polylines(out, [outline], True, colour, 1, cv2.LINE_AA, shift=2)
        a, b = windows.points[k, 0], windows.points[k, 1]
        if windows.kind[k] == CAPSULE:
            cv2.line(out, tuple(np.round(a * 4).astype(int)), tuple(np.round(b * 4).astype(int)),
                     colour, 1, cv2.LINE_AA, shift=2)
        centre = windows.points[k, :2].mean(axis=0) if windows.kind[k] == CAPSULE else \
            windows.points[k].mean(axis=0)
        label = str(rank[k] + 1) + (f" {names[k]}" if names else "")
        cv2.putText(out, label, tuple(np.round(centre).astype(int)), cv2.FONT_HERSHEY_SIMPLEX,
                    0.35, (255, 255, 255), 1, cv2.LINE_AA)
    return out


def residual_image(evaluation, width: int, height: int) -> np.ndarray:
    """(H, W) float32 image of the visible template residuals ``V r`` splatted at their
    pixels (grey levels of the filtered image; 0 elsewhere), for figures."""
    out = np.zeros((height, width), dtype=np.float32)
    w = np.round(evaluation.pixels).astype(int)
    keep = ((w[:, 0] >= 0) & (w[:, 0] < width) & (w[:, 1] >= 0) & (w[:, 1] < height)
            & (evaluation.visibility > 0))
    out[w[keep, 1], w[keep, 0]] = (evaluation.visibility * evaluation.residuals)[keep]
    return out
