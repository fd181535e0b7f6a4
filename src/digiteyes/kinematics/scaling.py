"""Uniformly scaled copies of a kinematic model (the user's hand size, thesis Sec. 2.2.3)."""

from __future__ import annotations

import dataclasses

import numpy as np

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


def model_of_size(model: KinematicModel, scale: float) -> KinematicModel:
    """``model`` itself at ``scale`` 1, else :func:`scaled_model` of it with its name: the
    model whose states are those of a hand ``scale`` times its size (e.g. a
    :attr:`~digiteyes.trackers.TrackResult.hand_scale`), for drawing and export."""
    return model if scale == 1.0 else scaled_model(model, scale, name=model.name)


def model_unit_states(model: KinematicModel, states: np.ndarray,
                      scale: float | np.ndarray) -> np.ndarray:
    """The states of ``model`` that pose ``1 / scale`` of a hand ``scale`` times the model's
    size at ``states`` (..., n_q): the base translation divided by ``scale`` (per state
    when ``scale`` is an array of the leading shape), the angles unchanged.

    A hand of size ``s`` at a state ``q`` (translation in mm, where the scaled hand's palm
    is) has the points ``s * p(model_unit_states(model, q, s))``, with ``p`` the points of
    the model file's hand (:func:`scaled_model`). A model without a pose base takes only
    ``scale`` 1 (its palm moves on joints of the model file's lengths).
    """
    states = np.array(states, dtype=float)
    scale = np.asarray(scale, dtype=float)
    if model.base_state is None:
        if np.any(scale != 1.0):
            raise DigitEyesError(f"model {model.name!r} has no pose base: its hand cannot be "
                                 "posed at another scale")
        return states
    k = model.base_state
    states[..., k + 4:k + 7] /= scale[..., None]
    return states
