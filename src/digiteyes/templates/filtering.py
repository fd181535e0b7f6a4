"""Laplacian-of-Gaussian filtering of images and templates (Rehg thesis Sec. 2.4.2, 4.4.2).

The thesis compares templates with images after a LoG filter: it removes the mean
brightness and slow shading, so a template taken under one lighting still fits a
frame with slightly different lighting, and it turns silhouettes into strong, smooth
responses that pull a misplaced template towards its link. Sec. 4.4.2 used a 13 x 13
kernel; the size and the Gaussian's sigma are options here.

**Contrast normalisation** (not in the thesis; ``contrast_px > 0``). The LoG removes
shading that is slow across the filter, but not the shading of a curved link: a capsule
lit from one side is bright on one flank and dark on the other, and as it bends towards
or away from the light its outline's contrast, and so the LoG response along it, grows
and shrinks. Templates acquired on the first frame then no longer match, and the layered
error's minimum leaves the truth (docs/templates.md measures this). Divisive normalisation
makes the response invariant to a gain that is locally constant:

    N(x) = c L(x) / sqrt( (G_s * L^2)(x) + f^2 ),

``L`` the LoG response, ``G_s *`` a Gaussian blur of width ``s = contrast_px``, ``f`` a
floor that keeps flat, noisy regions near 0 instead of blowing them up, and
``c = NORMALISED_RMS``: where contrast is high, the response has a local RMS of about
``c`` whatever the light, exposure or skin tone. The floor is ``contrast_floor`` or
``contrast_noise`` times the frame's noise level in ``L``, whichever is larger; the noise
level is estimated robustly as 1.4826 times the median of ``|L|`` over every fourth pixel
of every fourth row (most pixels of a frame are flat, so the median sees the noise, not
the edges).
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from digiteyes.errors import DigitEyesError
from digiteyes.features.slices import prepare_image

NORMALISED_RMS = 20.0
"""Local RMS of a contrast-normalised response where contrast is high (in the units of the
grey levels, so residual thresholds keep the same order as without normalisation)."""


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
    contrast_px : width ``s`` (px) of the Gaussian window of the contrast normalisation
        (module docstring); 0 switches it off (the thesis's plain LoG).
    contrast_floor : the least floor ``f`` of the normalisation, in units of the LoG
        response (grey levels times ``gain``): local contrast far below it is not
        amplified.
    contrast_noise : the floor is also at least this many times the frame's noise level
        (module docstring), so sensor noise is not amplified to edge strength.
    """

    size: int = 13
    sigma: float | None = None
    gain: float = 4.0
    contrast_px: float = 0.0
    contrast_floor: float = 4.0
    contrast_noise: float = 3.0

    def __post_init__(self) -> None:
        if self.size != 0 and (int(self.size) != self.size or self.size < 3
                               or self.size % 2 == 0):
            raise TemplateError(f"LoG size must be 0 (off) or an odd integer >= 3, "
                                f"got {self.size!r}")
        if self.sigma is not None and not self.sigma > 0:
            raise TemplateError(f"LoG sigma must be positive, got {self.sigma!r}")
        if not self.contrast_px >= 0:
            raise TemplateError(f"contrast_px must be 0 (off) or positive, got "
                                f"{self.contrast_px!r}")
        if not self.contrast_floor > 0:
            raise TemplateError(f"contrast_floor must be positive, got "
                                f"{self.contrast_floor!r}")
        if not self.contrast_noise >= 0:
            raise TemplateError(f"contrast_noise must be 0 or positive, got "
                                f"{self.contrast_noise!r}")

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

    def apply(self, image: np.ndarray, region: tuple[int, int, int, int] | None = None
              ) -> np.ndarray:
        """Filtered float32 (H, W) image of a grey or RGB ``image`` (contrast-normalised
        when ``contrast_px > 0``).

        ``region`` ``(u0, v0, u1, v1)`` (px, end exclusive) filters only that box and
        leaves the rest of the output 0: the box is cut with the filters' reach around it
        (the LoG's half size, four widths of the normalisation window: OpenCV's
        Gaussian reach), so inside it the
        result is what the whole image would give, except the noise level of the
        normalisation floor, which is then estimated from the box.
        """
        grey = prepare_image(image)
        if self.size == 0:
            return np.ascontiguousarray(grey, dtype=np.float32)
        if region is None:
            return self._filter(grey.astype(np.float32, copy=False))
        h, w = grey.shape
        reach = self.size // 2 + int(np.ceil(4.0 * self.contrast_px))
        u0, v0, u1, v1 = (max(0, int(region[0])), max(0, int(region[1])),
                          min(w, int(region[2])), min(h, int(region[3])))
        out = np.zeros((h, w), np.float32)
        if u1 <= u0 or v1 <= v0:
            return out
        cu0, cv0, cu1, cv1 = max(0, u0 - reach), max(0, v0 - reach), min(w, u1 + reach), \
            min(h, v1 + reach)
        crop = self._filter(np.ascontiguousarray(grey[cv0:cv1, cu0:cu1], dtype=np.float32))
        out[v0:v1, u0:u1] = crop[v0 - cv0:v1 - cv0, u0 - cu0:u1 - cu0]
        return out

    def _filter(self, grey: np.ndarray) -> np.ndarray:
        """The filter of a float32 grey image (module docstring)."""
        response = cv2.filter2D(grey, cv2.CV_32F, self.kernel,
                                borderType=cv2.BORDER_REPLICATE)
        if self.contrast_px == 0:
            return response
        sample = np.abs(response[::4, ::4]).ravel()
        middle = sample.size // 2
        noise = 1.4826 * float(np.partition(sample, middle)[middle])
        floor = max(float(self.contrast_floor), self.contrast_noise * noise)
        energy = cv2.GaussianBlur(cv2.multiply(response, response), (0, 0),
                                  float(self.contrast_px), borderType=cv2.BORDER_REPLICATE)
        return cv2.divide(response, cv2.sqrt(cv2.add(energy, floor * floor)),
                          scale=NORMALISED_RMS)
