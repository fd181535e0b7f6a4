"""The conditioning matrix ``S`` of thesis eq. 2.22 for a kinematic model.

``S`` is diagonal and constant; entry ``i`` penalises ``S_ii dv_i^2`` in each Gauss-Newton
step, so a large weight makes state ``i`` move only when the residuals insist (thesis
Sec. 2.5.3-2.5.4: it stabilises the solution near kinematic singularities). The thesis
used 1 for the quaternion, 10 for the translation and 1000 for the joint angles
(Table 4.2), with pixel residuals.

Two step layouts exist:

* ``form="tangent"`` (n_v entries, our default): the three rotation-step entries get the
  quaternion weight. A rotation by a small angle ``theta`` changes the unit quaternion by
  ``|dq| ~ theta / 2``, so the same weight damps a rotation four times harder here than in
  the thesis's quaternion form (penalty ``w theta^2`` vs ``w theta^2 / 4``); pass
  ``quaternion=0.25`` to reproduce the thesis's damping of rotation exactly.
* ``form="quaternion"`` (n_q entries): the thesis's layout, one weight per raw state.
"""

from __future__ import annotations

import numpy as np

from digiteyes.kinematics import KinematicModel
from digiteyes.kinematics.step_form import StepForm


def hand_conditioning(
    model: KinematicModel,
    quaternion: float = 1.0,
    translation: float = 10.0,
    joint: float = 1000.0,
    form: StepForm | str = StepForm.TANGENT,
) -> np.ndarray:
    """Diagonal of ``S`` (thesis eq. 2.22, Table 4.2) in the step layout of ``form``.

    Parameters
    ----------
    model : the kinematic model; state kinds decide the weights (``quat``, ``trans``,
        ``angle``; prismatic ``length`` states get the translation weight).
    quaternion, translation, joint : weights, px^2 per squared step unit (quaternion
        number or radian of rotation, mm, rad).
    form : ``"tangent"`` for (n_v,) weights, ``"quaternion"`` for (n_q,) weights.

    Returns
    -------
    (n_v,) or (n_q,) non-negative weights.
    """
    for name, value in (("quaternion", quaternion), ("translation", translation),
                        ("joint", joint)):
        if not (np.isfinite(value) and value >= 0):
            raise ValueError(f"{name} weight must be a non-negative number, got {value!r}")
    form = StepForm.parse(form)
    weight_of_kind = {"quat": quaternion, "trans": translation, "length": translation,
                      "angle": joint}
    per_state = np.array([weight_of_kind[kind] for kind in model.state_kinds], dtype=float)
    if form is StepForm.QUATERNION:
        return per_state
    S = np.empty(model.n_v)
    plain = model.q_to_v >= 0
    S[model.q_to_v[plain]] = per_state[plain]
    if model.base_state is not None:
        k = model.base_state
        S[k:k + 3] = quaternion
    return S
