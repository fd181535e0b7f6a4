"""Uniformly scaled copies of a kinematic model (the user's hand size, thesis Sec. 2.2.3)."""

from __future__ import annotations

import dataclasses

from digiteyes.errors import DigitEyesError
from digiteyes.kinematics.model import KinematicModel
from digiteyes.kinematics.model_file import ShapeSpec


def scaled_model(model: KinematicModel, scale: float, name: str | None = None) -> KinematicModel:
    """A copy of ``model`` with every length multiplied by ``scale`` (dimensionless): DH
    ``a`` and constant ``d``, cylinder and tip radii, palm box sizes and centre.

    Posed at a state whose base translation is ``scale`` times that of ``q``, it gives
    ``scale`` times the original's points at ``q`` (angles are unchanged).
    """
    if not scale > 0:
        raise DigitEyesError(f"model scale must be positive, got {scale!r}")
    frames = []
    for row in model.spec.frames:
        shape = row.shape
        if shape is not None:
            shape = ShapeSpec(shape.kind, tuple(scale * p for p in shape.params))
        d = row.d if row.d_state is not None else scale * row.d
        frames.append(dataclasses.replace(row, a=scale * row.a, d=d, shape=shape))
    spec = dataclasses.replace(model.spec, frames=tuple(frames),
                               description=f"{model.description} (scaled x{scale:.4f})")
    if name is not None:
        spec = dataclasses.replace(spec, name=name)
    return KinematicModel(spec)
