"""digiteyes: model-based 3D tracking of articulated objects, the human hand first.

The package follows the data flow of the DigitEyes system (Rehg, 1995): a kinematic model
read from a model file (:mod:`digiteyes.kinematics`), cameras (:mod:`digiteyes.camera`),
image measurements (:mod:`digiteyes.features`), solvers (:mod:`digiteyes.solvers`) and
trackers (:mod:`digiteyes.trackers`). Units are millimetres and radians throughout.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from digiteyes.errors import DigitEyesError
from digiteyes.version import __version__

if TYPE_CHECKING:
    from digiteyes.kinematics import KinematicModel, State, forward_kinematics, load_model

__all__ = ["DigitEyesError", "KinematicModel", "State", "__version__", "forward_kinematics",
           "load_model"]
_KINEMATICS = ("KinematicModel", "State", "forward_kinematics", "load_model")


def __getattr__(name: str) -> object:
    """Load the kinematics names on first use, so ``import digiteyes`` (and the start of
    the ``digiteyes`` command, where Ctrl-C must give one line) imports no numeric code."""
    if name in _KINEMATICS:
        from digiteyes import kinematics

        return getattr(kinematics, name)
    raise AttributeError(f"module 'digiteyes' has no attribute {name!r}")
