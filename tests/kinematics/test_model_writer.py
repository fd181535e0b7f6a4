"""format_model_text writes model files that parse back to the same model."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from digiteyes.kinematics import (
    KinematicModel,
    format_model_text,
    forward_kinematics,
    load_model,
    parse_model_text,
)
from digiteyes.models import shipped_models


def _without_lines(spec):
    states = tuple(dataclasses.replace(s, line=0) for s in spec.states)
    frames = tuple(dataclasses.replace(f, line=0) for f in spec.frames)
    return dataclasses.replace(spec, states=states, frames=frames, path="")


@pytest.mark.parametrize("name", shipped_models())
def test_round_trip_keeps_every_number(name: str) -> None:
    spec = load_model(name).spec
    again = parse_model_text(format_model_text(spec), "again.dh")
    assert _without_lines(again) == _without_lines(spec)


def test_perturbed_numbers_survive_exactly() -> None:
    spec = load_model("hand").spec
    frames = tuple(dataclasses.replace(f, a=f.a * (1 + 1e-7 * (i + 1)))
                   for i, f in enumerate(spec.frames))
    odd = dataclasses.replace(spec, frames=frames)
    model = KinematicModel(odd)
    again = KinematicModel(parse_model_text(format_model_text(odd)))
    q = model.neutral()
    q[7:] = np.linspace(-0.3, 0.3, model.n_q - 7)
    np.testing.assert_array_equal(forward_kinematics(again, q).T_world_frame,
                                  forward_kinematics(model, q).T_world_frame)


def test_a_model_without_states_has_fixed_frames() -> None:
    model = KinematicModel(parse_model_text(
        "model block\n[states]\n[frames]\n0 base 0 0 0 0 - 1\n1 arm pi/2 0 40 0 cyl(5) -\n"))
    kin = forward_kinematics(model, np.zeros(0))
    np.testing.assert_allclose(kin.T_world_frame[0, 1], np.eye(4))
    _, end, _ = kin.link_segments()
    np.testing.assert_allclose(end[0], [0.0, 40.0, 0.0], atol=1e-12)
    assert forward_kinematics(model, np.zeros((3, 0))).T_world_frame.shape == (3, 2, 4, 4)
