"""Backdrops behind the rendered model, as float32 images on the 0-255 scale.

* ``black``: the thesis's black cloth (Sec. 4.4.2): ``background_level`` with faint,
  smooth folds (a few grey levels of low-frequency shading, no edges);
* ``uniform``: exactly ``background_level`` everywhere;
* ``clutter``: a procedural scene of overlapping filled shapes, thick lines and texture
  in random colours, for testing trackers away from the black cloth;
* any other value: an image file, resized to the image size.

Procedural backdrops are seeded by ``(background_seed, camera index)`` rather than by the
renderer's ``rng``: a backdrop is part of the scene, fixed over the frames of a sequence,
and different for each camera of a rig. Results are cached and returned read-only.
"""

from __future__ import annotations

from functools import lru_cache
from pathlib import Path

import cv2
import numpy as np

from digiteyes.synth.options import RenderError, RenderOptions

_FOLD_AMPLITUDE = 0.025  # cloth fold shading, fraction of full scale
_CLUTTER_SHAPES = 70


def background(options: RenderOptions, width: int, height: int,
               camera_index: int = 0) -> np.ndarray:
    """The backdrop as float32 (H, W) or (H, W, 3) RGB on the 0-255 scale (read-only)."""
    kind = options.background
    if kind == "uniform":
        shape = (height, width, 3) if options.color else (height, width)
        return np.full(shape, 255.0 * options.background_level, dtype=np.float32)
    if kind in ("black", "clutter"):
        return _procedural(kind, options.background_level, options.color, width, height,
                           options.background_seed, camera_index)
    path = Path(kind)
    return _from_file(str(path.resolve()), path.stat().st_mtime, options.color, width, height)


@lru_cache(maxsize=16)
def _procedural(kind: str, level: float, color: bool, width: int, height: int, seed: int,
                camera_index: int) -> np.ndarray:
    rng = np.random.default_rng(np.random.SeedSequence([seed, camera_index]))
    if kind == "black":
        folds = _smooth_noise(rng, width, height, cells=6)
        image = 255.0 * np.clip(level + _FOLD_AMPLITUDE * folds, 0.0, 1.0)
        if color:
            image = np.repeat(image[..., None], 3, axis=2)
    else:
        image = _clutter(rng, width, height)
        if not color:
            image = cv2.cvtColor(image, cv2.COLOR_RGB2GRAY)
    out = np.ascontiguousarray(image, dtype=np.float32)
    out.flags.writeable = False
    return out


def _smooth_noise(rng: np.random.Generator, width: int, height: int, cells: int) -> np.ndarray:
    """Band-limited noise in about [-1, 1]: a coarse random grid upsampled bicubically."""
    coarse = rng.uniform(-1.0, 1.0, size=(cells + 1, cells + 1)).astype(np.float32)
    return cv2.resize(coarse, (width, height), interpolation=cv2.INTER_CUBIC)


def _clutter(rng: np.random.Generator, width: int, height: int) -> np.ndarray:
    """An RGB uint8 clutter image: smooth coloured base, random shapes, fine texture."""
    base = np.stack([_smooth_noise(rng, width, height, 4) for _ in range(3)], axis=2)
    image = np.clip(110.0 + 60.0 * base, 0, 255).astype(np.uint8)
    size = max(width, height)
    for _ in range(_CLUTTER_SHAPES):
        color = tuple(int(c) for c in rng.integers(0, 256, 3))
        centre = (int(rng.integers(0, width)), int(rng.integers(0, height)))
        extent = int(rng.integers(size // 40 + 1, size // 6 + 2))
        shape = rng.integers(0, 4)
        if shape == 0:
            corner = (centre[0] + int(rng.integers(-extent, extent + 1)),
                      centre[1] + int(rng.integers(-extent, extent + 1)))
            cv2.rectangle(image, centre, corner, color, -1, cv2.LINE_AA)
        elif shape == 1:
            cv2.circle(image, centre, extent // 2 + 1, color, -1, cv2.LINE_AA)
        elif shape == 2:
            axes = (extent, int(rng.integers(1, extent + 1)))
            cv2.ellipse(image, centre, axes, float(rng.uniform(0, 180)), 0, 360, color, -1,
                        cv2.LINE_AA)
        else:
            end = (centre[0] + int(rng.integers(-3 * extent, 3 * extent + 1)),
                   centre[1] + int(rng.integers(-3 * extent, 3 * extent + 1)))
            cv2.line(image, centre, end, color, int(rng.integers(1, 8)), cv2.LINE_AA)
    grain = rng.normal(0.0, 4.0, size=(height, width, 1))
    return np.clip(image + grain, 0, 255).astype(np.uint8)


@lru_cache(maxsize=8)
def _from_file(path: str, mtime: float, color: bool, width: int, height: int) -> np.ndarray:
    image = cv2.imread(path, cv2.IMREAD_COLOR)
    if image is None:
        raise RenderError(f"{path}: background is not a readable image file")
    image = cv2.resize(image, (width, height), interpolation=cv2.INTER_AREA)
    code = cv2.COLOR_BGR2RGB if color else cv2.COLOR_BGR2GRAY
    out = cv2.cvtColor(image, code).astype(np.float32)
    out.flags.writeable = False
    return out
