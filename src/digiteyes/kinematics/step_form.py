"""The form of a solver step: the one object every layer tests (DESIGN.md Sec. 3).

* :attr:`StepForm.TANGENT` (default): ``model.n_v`` numbers, a 3-vector rotation step of
  the palm quaternion then a retraction (:func:`~digiteyes.kinematics.state.integrate`).
* :attr:`StepForm.QUATERNION` (thesis Sec. 2.2.1): ``model.n_q`` numbers added to the raw
  state, the quaternion renormalised afterwards (with the conditioning of thesis eq. 2.22).

A ``StepForm`` is a ``str``, so ``"tangent"`` and ``"quaternion"`` are accepted wherever a
form is asked for; :meth:`StepForm.parse` turns either into the object and rejects
anything else.
"""

from __future__ import annotations

from enum import Enum
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from digiteyes.kinematics.model import KinematicModel


class StepForm(str, Enum):
    """How a step is laid out: tangent (n_v numbers) or the thesis's quaternion (n_q)."""

    TANGENT = "tangent"
    QUATERNION = "quaternion"

    @classmethod
    def parse(cls, value: StepForm | str) -> StepForm:
        """``value`` as a :class:`StepForm`; ValueError naming the choices otherwise."""
        try:
            return cls(value)
        except ValueError:
            raise ValueError(f"form must be 'tangent' or 'quaternion', got {value!r}") from None

    def n_columns(self, model: KinematicModel) -> int:
        """Numbers in one step of ``model``: ``n_v`` (tangent) or ``n_q`` (quaternion)."""
        return model.n_q if self is StepForm.QUATERNION else model.n_v

    def __str__(self) -> str:
        return self.value


STEP_FORMS = tuple(form.value for form in StepForm)
"""The accepted spellings, for option validation and command-line choices."""
