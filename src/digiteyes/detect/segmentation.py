"""Hand segmentation without learned parts: a skin-colour model, a background-colour model
from the image border (a plain wall), and per-pixel background statistics for a static
camera.

* **Skin** (colour images): chrominance in YCrCb inside a box that holds skin of every
  tone under white light (Cr 136..175, Cb 77..127; Chai & Ngan's box widened on the red
  side), which a grey wall (Cr = Cb = 128) fails; down to Cr 131 (skin washed out by dim
  or grey light) where that colour does not occur on the image border.
* **Border colour** (a plain wall): the colours that occur on the image border (a coarse
  colour histogram); a pixel of one of those colours is background.
* **Static background** (:class:`BackgroundModel`): mean and standard deviation of every
  pixel over the first frames of a static camera; foreground where a frame departs from
  them by more than ``k`` standard deviations.

The foreground is skin and not background (colour), or not background (grey images).
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass

import cv2
import numpy as np

from digiteyes.errors import DigitEyesError

SKIN_CR = (136, 175)
"""Skin chrominance Cr range (YCrCb, 8-bit)."""
SKIN_CB = (77, 127)
"""Skin chrominance Cb range (YCrCb, 8-bit)."""
WEAK_SKIN_CR = 131
"""Lower Cr edge for skin whose colour the light has washed out (dim or grey-lit skin),
accepted only where the colour does not occur on the image border."""


def skin_masks(rgb: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Bool (H, W) twice, from one colour conversion: pixels whose chrominance falls in the
    skin box, and those that fall in it with its Cr range widened down to
    :data:`WEAK_SKIN_CR` (washed-out skin, a superset)."""
    ycrcb = cv2.cvtColor(rgb, cv2.COLOR_RGB2YCrCb)
    washed = cv2.inRange(ycrcb, (0, WEAK_SKIN_CR, SKIN_CB[0]),
                         (255, SKIN_CR[1], SKIN_CB[1])) > 0
    return washed & (ycrcb[..., 1] >= SKIN_CR[0]), washed


def border_background(image: np.ndarray, width: int = 4, bin_levels: int = 16,
                      min_share: float = 0.005, exclude: np.ndarray | None = None
                      ) -> np.ndarray:
    """Bool (H, W): pixels whose colour occurs on the image border.

    The border pixels (a strip ``width`` px wide) fill a colour histogram with bins
    ``bin_levels`` grey levels wide per channel; bins holding at least ``min_share`` of
    them, grown by one bin in every direction, are the background colours, and each pixel
    is looked up in that table. A plain wall occupies a few bins; a wall with a window and
    a desk edge a few more. Border pixels where ``exclude`` (bool (H, W)) is set are left
    out: an arm crossing the border is not background.
    """
    img = np.asarray(image).reshape(*np.shape(image)[:2], -1)
    channels = img.shape[2]
    strip = np.zeros(img.shape[:2], dtype=bool)
    strip[:width] = strip[-width:] = True
    strip[:, :width] = strip[:, -width:] = True
    if exclude is not None and (strip & ~exclude).any():
        strip &= ~exclude
    bins = 256 // bin_levels
    index = img // bin_levels
    flat = np.zeros(img.shape[:2], dtype=np.int64)
    for c in range(channels):
        flat = flat * bins + index[..., c]
    counts = np.bincount(flat[strip], minlength=bins ** channels)
    table = (counts >= min_share * strip.sum()).reshape((bins,) * channels)
    grown = table.copy()
    for axis in range(channels):
        grown |= np.roll(table, 1, axis) | np.roll(table, -1, axis)
    table = grown
    return table.ravel()[flat]


@dataclass
class BackgroundModel:
    """Per-pixel mean and standard deviation of a static camera's background.

    Attributes
    ----------
    mean, std : float32 (H, W, C) grey levels; ``std`` floored at ``min_std``.
    threshold : a pixel is foreground when any channel departs by more than
        ``threshold * std``.
    """

    mean: np.ndarray
    std: np.ndarray
    threshold: float = 4.0

    @classmethod
    def from_frames(cls, frames: Iterable[np.ndarray], min_std: float = 4.0,
                    threshold: float = 4.0) -> BackgroundModel:
        """Statistics of frames showing the empty scene (the first frames of a video)."""
        stack = np.array([np.asarray(f, dtype=np.float32).reshape(*np.shape(f)[:2], -1)
                          for f in frames])
        if len(stack) == 0:
            raise DigitEyesError("background model: give at least one frame of the empty scene")
        return cls(stack.mean(0), np.maximum(stack.std(0), min_std), threshold)

    def foreground(self, image: np.ndarray) -> np.ndarray:
        """Bool (H, W): pixels departing from the background."""
        img = np.asarray(image, dtype=np.float32).reshape(*np.shape(image)[:2], -1)
        if img.shape != self.mean.shape:
            raise DigitEyesError(f"background model is {self.mean.shape[1]}x"
                                 f"{self.mean.shape[0]}, the image {img.shape[1]}x"
                                 f"{img.shape[0]}")
        return (np.abs(img - self.mean) > self.threshold * self.std).any(axis=2)


def hand_mask(image: np.ndarray, background: BackgroundModel | None = None) -> np.ndarray:
    """Bool (H, W) foreground, cleaned by a morphological opening and closing.

    * colour (RGB uint8): skin, and not background when a static ``background`` model is
      given. The border colours are not used: a hand's highlights and shadows reach the
      greys of a wall within a histogram bin, which cut fingers off on real footage, while
      the skin box alone already rejects a grey or white wall;
    * grey (also an RGB image whose three channels are equal): not background
      (``background`` when given, else the border colours).
    """
    image = np.asarray(image)
    if image.dtype != np.uint8 or image.ndim not in (2, 3):
        raise DigitEyesError(f"hand segmentation: expected a uint8 grey or RGB image, got "
                             f"{image.dtype} {image.shape}")
    if (image.ndim == 3 and background is None and image.shape[2] == 3
            and (image[..., 0] == image[..., 1]).all() and (image[..., 0] == image[..., 2]).all()):
        image = image[..., 0]  # a grey video decoded as RGB: no chrominance for the skin box
    if image.ndim == 3:
        skin, washed = skin_masks(image)
        fg = skin | (washed & ~border_background(image))
        if background is not None:
            fg &= background.foreground(image)
    elif background is not None:
        fg = background.foreground(image)
    else:
        fg = ~border_background(image)
    mask = cv2.morphologyEx(fg.astype(np.uint8), cv2.MORPH_OPEN,
                            cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (3, 3)))
    mask = cv2.morphologyEx(mask, cv2.MORPH_CLOSE,
                            cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (5, 5)))
    return mask > 0


def largest_blob(mask: np.ndarray) -> np.ndarray | None:
    """Bool (H, W) of the largest 8-connected component of ``mask`` (holes filled), or
    None when the mask is empty."""
    count, labels, stats, _ = cv2.connectedComponentsWithStats(mask.astype(np.uint8), 8)
    if count <= 1:
        return None
    biggest = 1 + int(np.argmax(stats[1:, cv2.CC_STAT_AREA]))
    blob = (labels == biggest).astype(np.uint8)
    contours, _ = cv2.findContours(blob, cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_NONE)
    cv2.drawContours(blob, contours, -1, 1, thickness=cv2.FILLED)
    return blob > 0
