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

APPEARANCES = ("model", "flesh")
"""How the hand is drawn: ``model`` from the tracking model's own solids (capsules, balls,
rounded slab; Lambert shading), ``flesh`` as an independent surface (docs/appearance.md)."""

SKIN_TONES = {
    "light": (0.93, 0.76, 0.66),
    "medium": (0.86, 0.64, 0.50),
    "olive": (0.74, 0.55, 0.39),
    "brown": (0.56, 0.39, 0.28),
    "dark": (0.36, 0.24, 0.18),
}
"""RGB diffuse albedo of named skin tones, light to dark (rounded values in the range of
measured skin reflectance at the red, green and blue bands)."""

_LUMA = (0.299, 0.587, 0.114)


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
    appearance : ``"model"`` (the tracking model's solids, Lambert) or ``"flesh"`` (an
        independent surface: tapered, blended phalanges, a fleshy palm and wrist, nails,
        textured skin, Blinn-Phong highlights; docs/appearance.md).
    skin_tone : None, or a name of :data:`SKIN_TONES`; replaces ``skin_rgb`` and
        ``skin_albedo`` (the tone's luma) in either appearance.
    specular, shininess : Blinn-Phong weight (of full white) and exponent of the skin
        highlights (flesh only).
    texture : relative depth of the skin's procedural albedo texture (flesh only).
    skin_seed : seed of that texture.
    shadows : the hand casts shadows on itself (flesh only).
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
    appearance: str = "model"
    skin_tone: str | None = None
    specular: float = 0.12
    shininess: float = 24.0
    texture: float = 0.08
    skin_seed: int = 0
    shadows: bool = False

    @property
    def skin_colour(self) -> tuple[float, float, float]:
        """RGB albedo of the skin: the named tone if any, else ``skin_rgb``."""
        return SKIN_TONES[self.skin_tone] if self.skin_tone else tuple(self.skin_rgb)

    @property
    def skin_grey(self) -> float:
        """Grey albedo of the skin: the tone's luma if a tone is named, else
        ``skin_albedo``."""
        if self.skin_tone:
            return float(sum(w * c for w, c in zip(_LUMA, SKIN_TONES[self.skin_tone],
                                                   strict=True)))
        return self.skin_albedo

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
        if self.appearance not in APPEARANCES:
            raise RenderError(f"appearance must be one of {', '.join(APPEARANCES)}, got "
                              f"{self.appearance!r}")
        if self.skin_tone is not None and self.skin_tone not in SKIN_TONES:
            raise RenderError(f"skin_tone must be None or one of {', '.join(SKIN_TONES)}, "
                              f"got {self.skin_tone!r}")
        _check_range("specular", self.specular, 0.0, 1.0)
        _check_range("texture", self.texture, 0.0, 1.0)
        _check_range("shininess", self.shininess, 1.0, 1000.0)
        if int(self.skin_seed) != self.skin_seed or self.skin_seed < 0:
            raise RenderError(f"skin_seed must be a non-negative integer, got {self.skin_seed}")
        if int(self.background_seed) != self.background_seed or self.background_seed < 0:
            raise RenderError(
                f"background_seed must be a non-negative integer, got {self.background_seed}"
            )


def _check_range(name: str, value: float, low: float, high: float) -> None:
    if not (isinstance(value, numbers.Real) and low <= value <= high):
        raise RenderError(f"{name} must be a number in [{low:g}, {high:g}], got {value!r}")
