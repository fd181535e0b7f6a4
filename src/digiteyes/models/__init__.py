"""Model files shipped with digiteyes, found by name (``model_path("hand")``); load one
with :func:`digiteyes.kinematics.load_model`, the one route to a model.

``hand`` (thesis Appendix A), ``mouse-hand`` (thesis Sec. 4.3.4), ``two-finger``
(Sec. 4.4.2) and ``cardboard-hand`` (Huang, Wu & Lin Sec. 2). See docs/models.md.
"""

from __future__ import annotations

from pathlib import Path

from digiteyes.errors import ModelFileError

MODEL_DIR = Path(__file__).parent
MAX_PATH = 1024
"""Longest model name or path accepted (characters)."""


def shipped_models() -> list[str]:
    """Names of the model files that ship with the package."""
    return sorted(p.stem for p in MODEL_DIR.glob("*.dh"))


def model_path(name_or_path: str | Path) -> Path:
    """Path of a shipped model name, or the given path if it is a file."""
    if not isinstance(name_or_path, (str, Path)):
        raise ModelFileError(repr(name_or_path)[:60], None, "a model is named by a str (a "
                             f"shipped name or a path), got {type(name_or_path).__name__}")
    if len(str(name_or_path)) > MAX_PATH or "\0" in str(name_or_path):
        raise ModelFileError(str(name_or_path)[:60] + "...", None,
                             f"model name or path longer than {MAX_PATH} characters or "
                             "holding a NUL character")
    candidate = Path(name_or_path)
    try:
        exists = candidate.exists()
    except OSError as exc:
        raise ModelFileError(str(name_or_path)[:60], None, f"cannot read ({exc.strerror})"
                             ) from None
    if candidate.suffix or exists or "/" in str(name_or_path):
        return candidate
    shipped = MODEL_DIR / f"{name_or_path}.dh"
    if not shipped.exists():
        raise ModelFileError(
            str(name_or_path), None,
            f"no shipped model of that name; shipped models are {', '.join(shipped_models())} "
            "(or give a path to a .dh file)",
        )
    return shipped
