"""digiteyes: model-based 3D tracking of articulated objects, the human hand first.

The package follows the data flow of the DigitEyes system (Rehg, 1995): a kinematic model
read from a model file (:mod:`digiteyes.kinematics`), cameras (:mod:`digiteyes.camera`),
image measurements (:mod:`digiteyes.features`), solvers (:mod:`digiteyes.solvers`) and
trackers (:mod:`digiteyes.trackers`). Units are millimetres and radians throughout.
"""

from digiteyes.errors import DigitEyesError
from digiteyes.kinematics import KinematicModel, State, forward_kinematics, load_model
from digiteyes.version import __version__

__all__ = ["DigitEyesError", "KinematicModel", "State", "__version__", "forward_kinematics",
           "load_model"]
