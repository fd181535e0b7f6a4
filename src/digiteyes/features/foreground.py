"""The hand's silhouette in an image of a static camera over a plain backdrop, and the
silhouette check of a pose: the signal that sees a finger the feature residual misses.

**Foreground** (:func:`fit_foreground`): on the first frame, where the pose is known, the
model's silhouette splits the image into hand and backdrop. The backdrop level ``b`` and
its spread ``s`` come from the pixels more than :data:`MARGIN_PX` outside the silhouette,
the hand's dark end ``h`` (the 5th percentile) from those more than :data:`MARGIN_PX`
inside. A pixel is foreground when its grey level exceeds
``threshold = max(b + 5 s, b + (h - b) / 2)`` (``b`` the median, ``s`` 1.4826 times the
median absolute deviation: robust to the parts of the real hand that the model's
silhouette does not cover) (a dark hand on a bright backdrop is the
mirror image). A backdrop whose spread ``s`` exceeds ``max_backdrop_std`` is looked at
again through a Gaussian blur of ``noise_blur_px``: sensor noise is independent from
pixel to pixel and the blur divides it by about 7, while a texture's blobs and stripes
survive it. If the blurred backdrop is plain enough the threshold is fitted, and every
frame is thresholded, on blurred images (a webcam in dim light, sensor noise of 8 grey
levels: the rule used to switch itself off); a textured backdrop still gives None: the
check then stays off. So does a threshold that keeps less than :data:`MIN_HAND_KEPT` of
the first frame's own hand pixels (a dark hand in shadow is as dark as the cloth): a
foreground that is not the hand would make every later comparison meaningless.

**Silhouette check** (:func:`silhouette_check`): draw the model's labels at the estimate
(:func:`digiteyes.render.raster.rasterise`) and compare with the foreground mask
(:func:`digiteyes.features.silhouette.silhouette_mismatch`), both grown by
``tolerance_px`` so that the differences of an exact hand and the model's capsules (a
fleshier palm, tapered fingers, a 10 % size difference) stay inside:

* ``unexplained``: foreground pixels beyond ``tolerance_px`` of the model silhouette, as
  a fraction of the model's pixels (a finger the pose has put elsewhere, or curled into
  the palm while the real one is out);
* per finger: the fraction of the finger's model pixels (its phalanges and tip) lying
  beyond ``tolerance_px`` of any foreground (a finger drawn over the backdrop).

Only the foreground connected to the model's silhouette (grown by ``tolerance_px``)
counts (:func:`connected_to`): another hand, or a person, elsewhere on the backdrop is
no part of this hand, and as it moved it made the unexplained share move with it (a
flesh render beside a second hand: 12 of 60 frames flagged lost for nothing). A pose
that has left the hand altogether still shows, as fingers drawn over the backdrop.

**Where an open digit would lie** (:func:`unexplained_where_open`): the share of the
pixels a digit would cover if it were extended, beyond the estimate's silhouette, that
are unexplained foreground. A finger the estimate has curled out of sight while the real
one is out leaves its pixels unexplained there; the global ``unexplained`` share can miss
it, because the tolerance band eats most of a thin finger's width.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from digiteyes.camera import Camera
from digiteyes.features.silhouette import silhouette_mismatch
from digiteyes.kinematics import KinematicModel, Kinematics
from digiteyes.kinematics.anatomy import DIGITS
from digiteyes.render.distortion import camera_canvas
from digiteyes.render.raster import rasterise
from digiteyes.render.scene import build_scene

MARGIN_PX = 6
"""Distance (px) from the first frame's silhouette of the pixels that fit the levels."""
MIN_HAND_KEPT = 0.5
"""Least share of the first frame's hand pixels (those more than :data:`MARGIN_PX` inside
the model's silhouette) that the fitted threshold must call hand; below it the grey levels
do not separate hand and backdrop (a dark hand in its own shadow over black cloth: 0-8 %
kept, where a lit one keeps 98-100 %) and :func:`fit_foreground` gives None."""
MIN_OPEN_PIXELS = 50
"""Fewest pixels of an open digit beyond the estimate for :func:`unexplained_where_open`."""
_LIGHT = np.array([0.0, 0.0, -1.0])


@dataclass(frozen=True)
class Foreground:
    """A grey-level threshold between hand and a plain backdrop.

    Attributes
    ----------
    threshold : grey level (0-255) between backdrop and hand.
    bright_hand : True when the hand is brighter than the backdrop.
    backdrop_level, backdrop_std : the backdrop's mean grey level and spread.
    blur_px : standard deviation (px) of the Gaussian blur applied before thresholding
        (0: none; a noisy sensor, :func:`fit_foreground`).
    """

    threshold: float
    bright_hand: bool
    backdrop_level: float
    backdrop_std: float
    blur_px: float = 0.0

    def mask(self, image: np.ndarray) -> np.ndarray:
        """Bool (H, W): the hand's pixels of a grey ``image``."""
        grey = _blurred(image, self.blur_px)
        return grey > self.threshold if self.bright_hand else grey < self.threshold


def _blurred(image: np.ndarray, sigma_px: float) -> np.ndarray:
    """A grey ``image`` as float32, through a Gaussian blur of ``sigma_px`` if positive."""
    grey = np.asarray(image, dtype=np.float32)
    return cv2.GaussianBlur(grey, (0, 0), sigma_px) if sigma_px > 0 else grey


def model_labels(model: KinematicModel, kin: Kinematics, camera: Camera,
                 index: int = 0) -> np.ndarray:
    """Label image (H, W) int16 of state ``index`` of ``kin`` in ``camera``: the link
    index of the model surface seen by each pixel, -1 off the model; drawn through the
    camera's lens distortion if it has any (the image's own pixels)."""
    scene = build_scene(model, kin, index).transformed(camera.T_cam_world)
    grid, warp = camera_canvas(camera)
    labels = rasterise(scene, grid, _LIGHT).labels
    return labels if warp is None else warp.warp(labels, nearest=True, fill=-1)


def hand_and_backdrop(labels: np.ndarray) -> tuple[np.ndarray, np.ndarray] | None:
    """Bool (H, W) masks of the pixels more than :data:`MARGIN_PX` inside and outside the
    model's silhouette in ``labels`` (H, W) (-1 off the model); None when either holds
    fewer than 50 pixels."""
    hit = (np.asarray(labels) >= 0).astype(np.uint8)
    kernel = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * MARGIN_PX + 1,) * 2)
    inside = cv2.erode(hit, kernel).astype(bool)
    outside = ~cv2.dilate(hit, kernel).astype(bool)
    return None if inside.sum() < 50 or outside.sum() < 50 else (inside, outside)


def robust_level(values: np.ndarray) -> tuple[float, float]:
    """Median and robust spread (1.4826 times the median absolute deviation) of grey
    levels ``values``."""
    level = float(np.median(values))
    return level, 1.4826 * float(np.median(np.abs(values - level)))


def fit_foreground(image: np.ndarray, labels: np.ndarray,
                   max_backdrop_std: float = 8.0, noise_blur_px: float = 2.0
                   ) -> Foreground | None:
    """Fit the threshold on a grey ``image`` (H, W) whose model ``labels`` (H, W) are
    known (the first frame at its true state); a backdrop spread beyond
    ``max_backdrop_std`` grey levels is measured again on the image blurred by
    ``noise_blur_px`` (module docstring; 0: never). None for a textured backdrop or an
    image without enough hand or backdrop pixels."""
    regions = hand_and_backdrop(labels)
    if regions is None:
        return None
    inside, outside = regions
    for blur_px in (0.0, noise_blur_px):
        grey = _blurred(image, blur_px)
        level, spread = robust_level(grey[outside])  # robust: the real hand reaches
        # beyond the model's silhouette (a wrist, a fleshier palm)
        if spread <= max_backdrop_std:
            break
    else:
        return None
    hand = grey[inside]
    bright = float(np.median(hand)) > level
    dark_end = float(np.percentile(hand, 5 if bright else 95))
    if bright:
        threshold = max(level + 5.0 * spread, level + 0.5 * (dark_end - level))
    else:
        threshold = min(level - 5.0 * spread, level + 0.5 * (dark_end - level))
    foreground = Foreground(threshold, bright, level, spread, blur_px)
    if foreground.mask(image)[inside].mean() < MIN_HAND_KEPT:
        return None  # the hand's own grey levels are the backdrop's: not separable
    return foreground


@dataclass(frozen=True)
class SilhouetteCheck:
    """One camera's silhouette check of a pose (fractions in [0, 1]).

    ``unexplained``: foreground beyond the tolerance of the model silhouette, per model
    pixel; ``finger_outside``: digit name -> fraction of its model pixels beyond the
    tolerance of the foreground (digits with fewer than ``min_pixels`` model pixels are
    left out); ``model_pixels``: the model's pixels; ``outside``: all model pixels beyond
    the tolerance of the foreground, per model pixel; ``link_pixels``: (n_links,) the
    model's pixels of each link (what the z-buffer shows of it); ``box``: (rows, cols)
    slices of the image box the comparison was made in (every model and foreground pixel
    lies inside it); ``unexplained_mask``, ``model_mask``: bool images of that box, the
    unexplained foreground pixels and the model's pixels; ``camera``: the index of the
    camera in its rig (set by the caller that checks several).
    """

    unexplained: float
    finger_outside: dict[str, float]
    model_pixels: int
    outside: float = 0.0
    link_pixels: np.ndarray | None = None
    box: tuple[slice, slice] | None = None
    unexplained_mask: np.ndarray | None = None
    model_mask: np.ndarray | None = None
    camera: int = 0


def digit_links(model: KinematicModel) -> dict[str, np.ndarray]:
    """Digit name -> indices of its links in ``model.links`` (digits the model has)."""
    out: dict[str, list[int]] = {}
    for i, link in enumerate(model.links):
        digit = link.name.split(".")[0]
        if digit in DIGITS:
            out.setdefault(digit, []).append(i)
    return {d: np.array(v) for d, v in out.items()}


def connected_to(mask: np.ndarray, seed: np.ndarray, reach_px: int) -> np.ndarray:
    """The parts of ``mask`` (H, W) uint8 (0 and one other value) connected
    (8-neighbourhood) to pixels within ``reach_px`` of ``seed`` (H, W) bool: the hand's
    own foreground, without another hand, an arm or a person elsewhere in the picture,
    which no pose of this hand explains (module docstring). ``mask`` itself when it is
    one piece or none.

    Beyond the labelling, the work is local: the components that touch the seed are
    found inside the seed's box, and each is drawn by a flood fill from one of its
    pixels (a cost of its own area, not the image's)."""
    count, parts = cv2.connectedComponents(mask, connectivity=8)
    if count <= 2:
        return mask
    x, y, w, h = cv2.boundingRect(seed.view(np.uint8))
    if not w:
        return np.zeros_like(mask)
    # the seed grown by reach_px, inside its own box (all that can touch it)
    y0, x0 = max(y - reach_px, 0), max(x - reach_px, 0)
    y1, x1 = y + h + reach_px, x + w + reach_px
    kernel = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * reach_px + 1,) * 2)
    grown = cv2.dilate(seed[y0:y1, x0:x1].view(np.uint8), kernel)
    rows, cols = np.nonzero((grown > 0) & (mask[y0:y1, x0:x1] > 0))
    _, first = np.unique(parts[y0:y1, x0:x1][rows, cols], return_index=True)
    filled = np.zeros((mask.shape[0] + 2, mask.shape[1] + 2), np.uint8)
    flags = 8 | cv2.FLOODFILL_MASK_ONLY | cv2.FLOODFILL_FIXED_RANGE | (1 << 8)
    for i in first:  # one pixel of each component that touches the seed
        cv2.floodFill(mask, filled, (int(cols[i] + x0), int(rows[i] + y0)), 0, 0, 0, flags)
    return filled[1:-1, 1:-1]


def silhouette_check(model: KinematicModel, kin: Kinematics, camera: Camera,
                     foreground: np.ndarray, tolerance_px: int = 5,
                     min_pixels: int = 150) -> SilhouetteCheck:
    """Compare the model drawn at the pose ``kin`` (one state) in ``camera`` with the
    ``foreground`` mask (H, W) bool of the same camera's image (module docstring)."""
    labels = model_labels(model, kin, camera)
    fg = connected_to(foreground.astype(np.uint8), labels >= 0, tolerance_px)
    # everything below happens inside the box of both silhouettes grown by the
    # structuring elements' reach; outside it both are empty, so the counts are the same
    u, v, w, h = cv2.boundingRect(fg | (labels >= 0).astype(np.uint8))
    pad = tolerance_px + 3
    rows = slice(max(v - pad, 0), v + h + pad)
    cols = slice(max(u - pad, 0), u + w + pad)
    labels, fg = labels[rows, cols], fg[rows, cols]
    kernel = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * tolerance_px + 1,) * 2)
    grown_fg = cv2.dilate(fg, kernel).astype(bool)
    grown_model = cv2.dilate((labels >= 0).astype(np.uint8), kernel)
    n_links = len(model.links)
    against_fg = silhouette_mismatch(grown_fg, labels, n_links)
    open_kernel = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (5, 5))
    extra = cv2.morphologyEx(fg & (1 - grown_model), cv2.MORPH_OPEN, open_kernel)
    model_pixels = against_fg.model_pixels
    unexplained = float(extra.sum()) / model_pixels if model_pixels else 1.0
    fingers = {}
    for digit, links in digit_links(model).items():
        pixels = int(against_fg.per_label_pixels[links].sum())
        if pixels >= min_pixels:
            fingers[digit] = int(against_fg.per_label_outside[links].sum()) / pixels
    outside = float(against_fg.per_label_outside.sum()) / model_pixels if model_pixels else 1.0
    return SilhouetteCheck(unexplained, fingers, model_pixels, outside,
                           against_fg.per_label_pixels, (rows, cols), extra.astype(bool),
                           labels >= 0)


def unexplained_where_open(check: SilhouetteCheck, open_labels: np.ndarray,
                           links: np.ndarray, min_pixels: int = MIN_OPEN_PIXELS
                           ) -> float | None:
    """Share of the pixels where a digit would lie if it were open that ``check`` found
    to be unexplained foreground: ``open_labels`` (H, W) are the model's labels with the
    digit extended (:func:`model_labels` of
    :func:`~digiteyes.kinematics.anatomy.open_digits`), ``links`` its link indices. Only
    the open digit's pixels beyond the checked estimate's own model count. None when
    fewer than ``min_pixels`` are left (the open digit lies over the estimate)."""
    if check.box is None or check.unexplained_mask is None or check.model_mask is None:
        return None
    region = np.isin(open_labels, links)
    inside = region[check.box]
    area = int(region.sum()) - int((inside & check.model_mask).sum())
    if area < min_pixels:
        return None
    return float((inside & check.unexplained_mask).sum()) / area
