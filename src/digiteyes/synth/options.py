"""Scene and sensor settings of the synthetic renderer, validated at construction.

The defaults imitate the thesis set-up: a hand in front of a black cloth backdrop
(thesis Sec. 4.4.2: "All of the experiments in this chapter employed a black cloth
backdrop"), lit by one distant light, seen by grey-level cameras.
"""

from __future__ import annotations

import math
import numbers
from dataclasses import dataclass
from pathlib import Path

from digiteyes.errors import DigitEyesError

BACKGROUNDS = ("black", "uniform", "clutter")
"""Named backgrounds; any other value of ``RenderOptions.background`` is an image path."""


class RenderError(DigitEyesError, ValueError):
    """Bad render options or inputs (names the option and what was expected)."""


@dataclass(frozen=True)
class RenderOptions:
    """How to render: image type, backdrop, light, skin and sensor effects.

    Attributes
    ----------
    color : False for grey-level uint8 (H, W) images, True for RGB uint8 (H, W, 3).
    background : ``"black"`` (the thesis's black cloth: ``background_level`` with faint,
        smooth folds), ``"uniform"`` (exactly ``background_level`` everywhere),
        ``"clutter"`` (procedural shapes and texture), or a path to an image file (resized
        to the image size).
    background_level : grey level of the black cloth and the uniform backdrop, in [0, 1].
    background_seed : seed of the procedural backdrops (cloth folds, clutter). The backdrop
        is part of the scene, so it stays the same from frame to frame whatever ``rng`` the
        renderer gets; each camera of a rig sees its own pattern.
    light_dir : world direction towards a distant light (normalised inside), or None for a
        headlight: a light at each camera, shining along its optical axis.
    ambient : ambient fraction in [0, 1]; Lambert shading gives
        ``albedo * (ambient + (1 - ambient) * max(0, n . l))``.
    skin_albedo : grey-level albedo of the skin, in [0, 1].
    skin_rgb : RGB albedo of the skin for colour images, each in [0, 1].
    noise_sigma : standard deviation of additive Gaussian sensor noise, grey levels (0-255).
    blur_sigma : standard deviation of a Gaussian blur (optics), pixels; 0 for none.
    supersample : samples per pixel along each image axis for anti-aliasing (1 = off);
        depth and labels are always sampled once, at the pixel centres.
    """

    color: bool = False
    background: str = "black"
    background_level: float = 0.08
    background_seed: int = 0
    light_dir: tuple[float, float, float] | None = (0.3, -0.4, 1.0)
    ambient: float = 0.25
    skin_albedo: float = 0.85
    skin_rgb: tuple[float, float, float] = (0.90, 0.70, 0.58)
    noise_sigma: float = 0.0
    blur_sigma: float = 0.0
    supersample: int = 1

    def __post_init__(self) -> None:
        if self.background not in BACKGROUNDS and not Path(self.background).is_file():
            raise RenderError(
                f"background must be one of {', '.join(BACKGROUNDS)} or the path of an image "
                f"file; got {self.background!r} (no such file)"
            )
        for name in ("background_level", "ambient", "skin_albedo"):
            _check_range(name, getattr(self, name), 0.0, 1.0)
        for name in ("noise_sigma", "blur_sigma"):
            _check_range(name, getattr(self, name), 0.0, math.inf)
        light = None if self.light_dir is None else tuple(self.light_dir)
        if light is not None and (len(light) != 3 or not all(math.isfinite(v) for v in light)
                                  or math.hypot(*light) == 0.0):
            raise RenderError(
                f"light_dir must be a finite non-zero 3-vector or None, got {light}")
        skin = tuple(self.skin_rgb)
        if len(skin) != 3 or not all(0.0 <= v <= 1.0 for v in skin):
            raise RenderError(f"skin_rgb must be three values in [0, 1], got {skin}")
        if int(self.supersample) != self.supersample or not 1 <= self.supersample <= 8:
            raise RenderError(f"supersample must be an integer in 1..8, got {self.supersample}")
        if int(self.background_seed) != self.background_seed or self.background_seed < 0:
            raise RenderError(
                f"background_seed must be a non-negative integer, got {self.background_seed}"
            )


def _check_range(name: str, value: float, low: float, high: float) -> None:
    if not (isinstance(value, numbers.Real) and low <= value <= high):
        raise RenderError(f"{name} must be a number in [{low:g}, {high:g}], got {value!r}")
