"""How a solver steps a kinematic state: tangent retraction or the thesis's quaternion form.

* ``"tangent"`` (default): steps have ``model.n_v`` numbers (a 3-vector world-frame
  rotation for the base) and are applied with
  :func:`~digiteyes.kinematics.integrate`, like pinocchio's ``integrate``.
* ``"quaternion"`` (thesis Sec. 2.2.1): steps have ``model.n_q`` numbers and are added to
  the raw state; the quaternion is then renormalised. The Jacobian columns are those of
  ``point_jacobian(form="quaternion")`` (derivatives of the normalised rotation with
  respect to the four raw numbers). The scale direction of the quaternion does not change
  any residual, so ``J^T J`` is singular there: the conditioning matrix ``S`` (or the
  solver's pseudo-inverse) keeps that step component bounded.
"""

from __future__ import annotations

import numpy as np

from digiteyes.kinematics import KinematicModel, clip_to_limits, integrate
from digiteyes.kinematics.step_form import StepForm


class StateParameterisation:
    """Retraction and projection of kinematic states for one step form.

    Parameters
    ----------
    model : the kinematic model.
    form : the :class:`~digiteyes.kinematics.step_form.StepForm` (or its spelling).
    clip : whether :meth:`project` clips joint and translation states into their limits.
    """

    def __init__(self, model: KinematicModel, form: StepForm | str = StepForm.TANGENT,
                 clip: bool = True) -> None:
        self.model = model
        self.form = StepForm.parse(form)
        self.clip = bool(clip)
        self.n_v = self.form.n_columns(model)

    def retract(self, q: np.ndarray, dv: np.ndarray) -> np.ndarray:
        """State reached from ``q`` (n_q,) by the step ``dv`` (n_v,) of this form."""
        if self.form is StepForm.TANGENT:
            return integrate(self.model, q, dv)
        out = np.asarray(q, dtype=float) + dv
        k = self.model.base_state
        if k is not None:
            out[k:k + 4] /= np.linalg.norm(out[k:k + 4])
        return out

    def project(self, q: np.ndarray) -> np.ndarray:
        """Clip into the joint limits (when ``clip``), else return ``q`` unchanged."""
        return clip_to_limits(self.model, q) if self.clip else q
