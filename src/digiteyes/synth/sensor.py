"""Sensor effects applied to the composed image: optical blur, noise, quantisation."""

from __future__ import annotations

import cv2
import numpy as np


def expose(image: np.ndarray, blur_sigma: float, noise_sigma: float,
           rng: np.random.Generator) -> np.ndarray:
    """Turn a float image on the 0-255 scale into uint8.

    A Gaussian blur of ``blur_sigma`` px (optics) comes first, then additive Gaussian noise
    of ``noise_sigma`` grey levels (sensor), then clipping and rounding.
    """
    out = np.array(image, dtype=np.float32)
    if blur_sigma > 0.0:
        out = cv2.GaussianBlur(out, (0, 0), blur_sigma, borderType=cv2.BORDER_REFLECT)
    if noise_sigma > 0.0:
        out += np.float32(noise_sigma) * rng.standard_normal(out.shape, dtype=np.float32)
    np.rint(out, out=out)
    np.clip(out, 0, 255, out=out)
    return out.astype(np.uint8)
