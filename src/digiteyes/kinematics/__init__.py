"""Kinematics: model files, the frame tree, states, forward kinematics, point Jacobians."""

from digiteyes.kinematics.forward import Kinematics, dh_transform, forward_kinematics
from digiteyes.kinematics.jacobian import point_jacobian
from digiteyes.kinematics.model import KinematicModel, Link, load_model, model_from_file
from digiteyes.kinematics.model_file import format_model_text, parse_model_text, read_model_file
from digiteyes.kinematics.state import (
    State,
    clip_to_limits,
    difference,
    held_at_limits,
    integrate,
    read_states_csv,
    resample_states,
    validate_state,
    write_states_csv,
)
from digiteyes.kinematics.step_form import STEP_FORMS, StepForm

__all__ = [
    "STEP_FORMS", "KinematicModel", "Kinematics", "Link", "State", "StepForm",
    "clip_to_limits", "dh_transform", "difference", "format_model_text", "forward_kinematics",
    "held_at_limits", "integrate", "load_model", "model_from_file", "parse_model_text",
    "point_jacobian", "read_model_file", "read_states_csv", "resample_states",
    "validate_state", "write_states_csv",
]
