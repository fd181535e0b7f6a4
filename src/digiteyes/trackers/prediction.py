"""Where the solver starts in each frame (thesis Sec. 2.4.3).

The thesis starts from the previous estimate, "possibly modified by velocity-based
prediction". We offer both:

* ``"none"``: the previous estimate;
* ``"constant-velocity"``: the previous estimate moved on by the last inter-frame motion,
  measured and applied in the tangent space (``v = difference(q_{k-2}, q_{k-1})``,
  ``q_pred = integrate(q_{k-1}, v)``), so the palm rotation extrapolates as a rotation.

A frame flagged as lost contributes no velocity: after a loss the prediction falls back to
the last estimate rather than extrapolating a motion that was not observed.
"""

from __future__ import annotations

from typing import Literal

import numpy as np

from digiteyes.kinematics import KinematicModel, clip_to_limits, difference, integrate

PredictionKind = Literal["constant-velocity", "none"]
PREDICTIONS = ("constant-velocity", "none")


class StatePredictor:
    """Predict the next state from the past estimates.

    Parameters
    ----------
    model : the kinematic model.
    kind : ``"constant-velocity"`` or ``"none"``.
    clip : clip predictions into the joint limits.
    """

    def __init__(self, model: KinematicModel, kind: PredictionKind = "constant-velocity",
                 clip: bool = True) -> None:
        if kind not in PREDICTIONS:
            raise ValueError(f"prediction must be 'constant-velocity' or 'none', got {kind!r}")
        self.model = model
        self.kind = kind
        self.clip = clip
        self.state: np.ndarray | None = None
        self.velocity = np.zeros(model.n_v)

    def reset(self, q: np.ndarray) -> None:
        """Start from ``q`` (n_q,) at rest."""
        self.state = np.array(q, dtype=float)
        self.velocity = np.zeros(self.model.n_v)

    def predict(self) -> np.ndarray:
        """The predicted state (n_q,) for the next frame."""
        if self.state is None:
            raise ValueError("the predictor has no state: call reset() first")
        if self.kind == "none" or not self.velocity.any():
            return self.state.copy()
        q = integrate(self.model, self.state, self.velocity)
        return clip_to_limits(self.model, q) if self.clip else q

    def update(self, q: np.ndarray, reliable: bool = True) -> None:
        """Record the estimate ``q`` of the frame just processed; an unreliable (lost)
        estimate resets the velocity to zero."""
        if self.state is None:
            raise ValueError("the predictor has no state: call reset() first")
        q = np.array(q, dtype=float)
        if reliable and self.kind == "constant-velocity":
            self.velocity = difference(self.model, self.state, q)
        else:
            self.velocity = np.zeros(self.model.n_v)
        self.state = q
