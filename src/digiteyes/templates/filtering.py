"""Laplacian-of-Gaussian filtering of images and templates (Rehg thesis Sec. 2.4.2, 4.4.2).

The thesis compares templates with images after a LoG filter: it removes the mean
brightness and slow shading, so a template taken under one lighting still fits a
frame with slightly different lighting, and it turns silhouettes into strong, smooth
responses that pull a misplaced template towards its link. Sec. 4.4.2 used a 13 x 13
kernel; the size and the Gaussian's sigma are options here.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from digiteyes.errors import DigitEyesError
from digiteyes.features.slices import prepare_image


class TemplateError(DigitEyesError, ValueError):
    """Bad template options or inputs (names the option and what was expected)."""


@dataclass(frozen=True)
class LogFilter:
    """A normalised Laplacian-of-Gaussian filter.

    Attributes
    ----------
    size : kernel side in pixels (odd; thesis Sec. 4.4.2: 13). 0 switches filtering off.
    sigma : Gaussian standard deviation, px; ``None`` gives ``size / 6``.
    gain : the response is multiplied by this (grey levels per grey level of curvature),
        so that residuals have a few-grey-level scale like the images.
    """

    size: int = 13
    sigma: float | None = None
    gain: float = 4.0

    def __post_init__(self) -> None:
        if self.size != 0 and (int(self.size) != self.size or self.size < 3
                               or self.size % 2 == 0):
            raise TemplateError(f"LoG size must be 0 (off) or an odd integer >= 3, "
                                f"got {self.size!r}")
        if self.sigma is not None and not self.sigma > 0:
            raise TemplateError(f"LoG sigma must be positive, got {self.sigma!r}")

    @property
    def kernel(self) -> np.ndarray:
        """The (size, size) float32 kernel, zero-mean, scaled by ``-sigma^2 * gain``
        (a bright blob gives a positive response)."""
        sigma = self.size / 6.0 if self.sigma is None else float(self.sigma)
        half = self.size // 2
        y, x = np.mgrid[-half:half + 1, -half:half + 1].astype(float)
        r2 = (x * x + y * y) / (2.0 * sigma * sigma)
        g = np.exp(-r2)
        lap = (r2 - 1.0) * g / (np.pi * sigma ** 4)
        lap -= lap.mean()
        return np.float32(-sigma * sigma * self.gain) * lap.astype(np.float32)

    def apply(self, image: np.ndarray) -> np.ndarray:
        """Filtered float32 (H, W) image of a grey or RGB ``image``."""
        grey = prepare_image(image)
        grey = grey.astype(np.float32) if grey.dtype != np.float32 else grey
        if self.size == 0:
            return np.ascontiguousarray(grey)
        return cv2.filter2D(grey, cv2.CV_32F, self.kernel, borderType=cv2.BORDER_REPLICATE)
