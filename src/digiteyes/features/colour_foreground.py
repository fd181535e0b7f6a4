"""The hand's silhouette in colour images over a textured backdrop: a colour model learned
on the first frame, where the pose is known.

The grey-level foreground of :mod:`digiteyes.features.foreground` needs a plain backdrop;
over clutter (a room, a patterned cloth) it gives none, and the silhouette loss rule
stays silent however wrong the estimate is. In colour the hand still stands apart from
most backdrops, by its skin's chrominance. :func:`fit_colour_foreground` splits the first
frame by the model's silhouette at the known state, as the grey fit does (the pixels
more than ``margin_px`` inside it are hand, those more than ``margin_px`` outside are
backdrop), and counts both in a histogram over YCrCb colour (:data:`BINS`: coarse in the
luma Y, which shading moves, fine in the chrominance Cr, Cb). A colour is hand where its
share of the hand's pixels exceeds its share of the backdrop's (the likelihood ratio
test with equal priors; counts smoothed by one). The model is kept only when it
separates its own first frame: at least :data:`MIN_HAND_RECALL` of the hand's pixels
and at most :data:`MAX_BACKDROP_SHARE` of the backdrop's fall on the hand's side. A
backdrop with much skin-coloured clutter (wood, another person) fails that and the rule
stays off, as before.

The mask of a frame is a look-up of each pixel's bin in that table, in one compiled pass
over the YCrCb image (numba: the numpy version's bin arithmetic and look-up cost 1.4 ms a
640x360 frame, the compiled pass 0.1 ms).
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np
from numba import njit

BINS = (8, 32, 32)
"""Histogram bins over Y, Cr and Cb (8-bit YCrCb): 32, 8 and 8 levels wide."""
_SHIFTS = (5, 3, 3)  # log2 of the bin widths
MIN_HAND_RECALL = 0.9
"""Share of the first frame's hand pixels the model must call hand."""
MAX_BACKDROP_SHARE = 0.10
"""Largest share of the first frame's backdrop pixels the model may call hand. Only the
foreground connected to the model's silhouette counts in the rule (and only its change
since the first frame), so scattered backdrop pixels of skin colour cost little; a
backdrop of which a tenth looks like skin is taken as too close to the hand."""


def is_colour(image: np.ndarray) -> bool:
    """Whether ``image`` is an (H, W, 3) colour image (RGB)."""
    return np.ndim(image) == 3 and np.shape(image)[2] == 3


@njit(cache=True)
def _lookup_kernel(ycrcb, is_hand, shifts, bins, out):  # pragma: no cover - compiled
    """``out[r, c] = is_hand[bin of ycrcb[r, c]]``, the bin as :func:`colour_bins` forms
    it from ``shifts`` and ``bins`` (tested equal)."""
    for r in range(ycrcb.shape[0]):
        for c in range(ycrcb.shape[1]):
            index = ((ycrcb[r, c, 0] >> shifts[0]) * bins[1]
                     + (ycrcb[r, c, 1] >> shifts[1])) * bins[2] + (ycrcb[r, c, 2] >> shifts[2])
            out[r, c] = is_hand[index]


def colour_bins(image: np.ndarray) -> np.ndarray:
    """The :data:`BINS` bin of every pixel of an RGB ``image`` (H, W, 3) uint8, as one
    flat index (H, W) int32 into a histogram of that shape."""
    ycrcb = cv2.cvtColor(np.ascontiguousarray(image, dtype=np.uint8), cv2.COLOR_RGB2YCrCb)
    y, cr, cb = (ycrcb[..., c].astype(np.int32) >> s for c, s in enumerate(_SHIFTS))
    return (y * BINS[1] + cr) * BINS[2] + cb


@dataclass(frozen=True)
class ColourForeground:
    """A colour model of hand and backdrop (module docstring).

    Attributes
    ----------
    is_hand : bool (prod(BINS),): the colour bins that are the hand's (flat
        :func:`colour_bins` index).
    hand_recall, backdrop_share : how the model split its own first frame (fractions).
    """

    is_hand: np.ndarray
    hand_recall: float
    backdrop_share: float

    def mask(self, image: np.ndarray) -> np.ndarray:
        """Bool (H, W): the hand's pixels of an RGB ``image`` (H, W, 3) uint8."""
        ycrcb = cv2.cvtColor(np.ascontiguousarray(image, dtype=np.uint8), cv2.COLOR_RGB2YCrCb)
        out = np.empty(ycrcb.shape[:2], dtype=bool)
        _lookup_kernel(ycrcb, self.is_hand, np.array(_SHIFTS), np.array(BINS), out)
        return out


def fit_colour_foreground(image: np.ndarray, labels: np.ndarray, margin_px: int
                          ) -> ColourForeground | None:
    """The colour model of an RGB ``image`` (H, W, 3) uint8 whose model ``labels`` (H, W)
    are known (the first frame at its true state; -1 off the model), or None when it
    does not separate the frame's hand from its backdrop (module docstring) or either
    holds fewer than 50 pixels."""
    if not is_colour(image):
        return None
    hit = (np.asarray(labels) >= 0).astype(np.uint8)
    kernel = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * margin_px + 1,) * 2)
    inside = cv2.erode(hit, kernel)
    outside = 1 - cv2.dilate(hit, kernel)
    n_inside, n_outside = int(inside.sum()), int(outside.sum())
    if n_inside < 50 or n_outside < 50:
        return None
    bins = colour_bins(image)
    size = int(np.prod(BINS))
    hand = np.bincount(bins[inside > 0], minlength=size).astype(float)
    backdrop = np.bincount(bins[outside > 0], minlength=size).astype(float)
    is_hand = (hand + 1.0) / (n_inside + size) > (backdrop + 1.0) / (n_outside + size)
    is_hand &= hand > 0  # a colour the hand never showed is not the hand's
    recall = float(hand[is_hand].sum()) / n_inside
    share = float(backdrop[is_hand].sum()) / n_outside
    if recall < MIN_HAND_RECALL or share > MAX_BACKDROP_SHARE:
        return None
    return ColourForeground(is_hand, recall, share)


__all__ = ["BINS", "MAX_BACKDROP_SHARE", "MIN_HAND_RECALL", "ColourForeground",
           "colour_bins", "fit_colour_foreground", "is_colour"]
