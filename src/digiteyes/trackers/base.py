"""The interface every tracker shares (DESIGN.md Sec. 5): ``reset`` then ``step`` per frame."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any, Protocol, runtime_checkable

import numpy as np

from digiteyes.solvers import SolverSummary

TIMING_STAGES = ("prediction", "shading", "forward_kinematics", "feature_detection",
                 "jacobian", "linear_solve", "total")


@dataclass
class TrackResult:
    """What a tracker reports for one frame.

    Attributes
    ----------
    state : (n_q,) estimated state (mm, rad, unit quaternion).
    residual_rms_px : root mean square of the final residual vector, pixels (NaN when no
        feature was measured).
    cost : final cost ``sum_i rho(r_i)`` of the solver, px^2.
    lost : the track-loss rules fired in this frame; tracking goes on regardless.
    loss_reason : why (``""`` when not lost; several reasons are joined by ``"; "``).
    iterations : solver iterations spent on this frame.
    summary : the solver's :class:`~digiteyes.solvers.SolverSummary`.
    measurements : one measurement object per camera at the final state (for overlays).
    residual_layouts : one residual layout per camera (which rows belong to which feature).
    residuals : (M,) final stacked residual vector over all cameras, px.
    n_valid_links, n_valid_tips : features measured at the final state, all cameras.
    n_features : features asked for (links + tips, times cameras).
    predicted_state : (n_q,) the prediction the solver started from.
    frame_index : frames stepped since the last :meth:`Tracker.reset` (0 for the first).
    timings : seconds per stage for this frame, summed over iterations (thesis Table 4.1
        rows): ``"prediction"``, ``"forward_kinematics"``, ``"feature_detection"``,
        ``"jacobian"`` (residual and Jacobian assembly), ``"linear_solve"`` (normal
        equations, solve, state update) and ``"total"`` (the whole ``step`` call).
    """

    state: np.ndarray
    residual_rms_px: float
    cost: float
    lost: bool
    loss_reason: str
    iterations: int
    summary: SolverSummary
    measurements: list[Any] = field(default_factory=list)
    residual_layouts: list[Any] = field(default_factory=list)
    residuals: np.ndarray = field(default_factory=lambda: np.zeros(0))
    n_valid_links: int = 0
    n_valid_tips: int = 0
    n_features: int = 0
    predicted_state: np.ndarray | None = None
    frame_index: int = 0
    timings: dict[str, float] = field(default_factory=dict)


@runtime_checkable
class Tracker(Protocol):
    """One interface for every tracker. Trackers never read files; ``io/`` and the CLI do.

    ``frames`` holds one image per camera of the tracker's rig, in rig order.
    """

    def reset(self, initial_state: np.ndarray) -> None:
        """Start a new track from ``initial_state`` (n_q,)."""
        ...

    def step(self, frames: Sequence[np.ndarray]) -> TrackResult:
        """Estimate the state for the next set of frames."""
        ...
