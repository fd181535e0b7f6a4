"""The 3D mouse of thesis Sec. 4.3.4 (Fig. 4.9, 4.12): hand states to a "mouse pole" cursor.

The graphical cursor is a pole standing on a ground plane; its base moves on the plane and
its top is the 3D cursor. The thesis drives it with a hand on a table, tracked with the
reduced mouse-hand model (``mouse-hand.dh``: palm sliding and turning on the table, index
finger with three joints, little finger and thumb that turn in the table plane):

* **pole base** = the palm position in the table plane: world x and y (mm) of the palm
  frame's origin (for ``mouse-hand`` exactly the states ``palm.x`` and ``palm.y``). That
  origin lies within 6 mm of the palm's centre, 38 mm behind the knuckles, and is the
  point :func:`digiteyes.evaluate.metrics.palm_pose` scores as the palm position;
* **pole height** = the height of the index fingertip above the table: world z of the
  ``index.tip`` sphere centre minus its radius, i.e. the height of the fingertip's lowest
  point (mm). In ``mouse-hand.dh`` the finger axes run 7.5 mm above the table and the tip
  radius is 9 mm, so a finger lying flat gives -1.5 mm (the model's tip sphere dips into
  the table); raising the finger by an MCP extension of 30 degrees gives about 46 mm;
* **buttons** = the thumb and the little finger abducted in the table plane beyond a
  threshold (states ``thumb.abd`` and ``little.abd``; positive moves the digit away from
  the other fingers).

World frame: the tabletop, z up out of the table, millimetres (docs/scenarios.md). The
thesis derives the pole "through scaling and a coordinate change"; a graphics
application applies its own scale and origin to the millimetres returned here.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from matplotlib.figure import Figure

from digiteyes.errors import StateError
from digiteyes.kinematics import KinematicModel, forward_kinematics, validate_state
from digiteyes.viz.plots import ESTIMATE_STYLE, TRUTH_STYLE, new_figure, save_figure

POLE_TIP = "index.tip"
"""The fingertip whose height above the table sets the pole height."""

BUTTONS = {"thumb": "thumb.abd", "little": "little.abd"}
"""Button name -> the abduction state that presses it."""

DEFAULT_BUTTON_THRESHOLD_DEG = 12.5
"""Abduction (degrees) beyond which a button counts as pressed: half the 25-degree thumb
stroke of the ``mouse`` scenario's button event (thesis Fig. 4.11, frames 158-192)."""


def palm_row(model: KinematicModel) -> int:
    """The row of ``model``'s palm link; :class:`StateError` when it has none."""
    palms = [link for link in model.links if link.kind == "palm"]
    if not palms:
        raise StateError(f"model {model.name!r} has no palm link: no mouse-pole base")
    return palms[0].row


def pole_from_state(model: KinematicModel, q: np.ndarray) -> np.ndarray:
    """The mouse pole of hand state(s) ``q``: base x, base y and height, world mm.

    Parameters
    ----------
    model : a hand on a table (world = tabletop, z up), with a palm link and an
        ``index.tip`` sphere; normally ``load_model("mouse-hand")``.
    q : (n_q,) or (N, n_q) states.

    Returns
    -------
    (3,) or (N, 3) array: ``x, y`` of the palm frame's origin and the height of the index
    fingertip's lowest point above the table (tip-centre z minus the tip radius), mm.

    Raises :class:`StateError` for a state of the wrong size or a model without a palm or
    an index tip.
    """
    Q = validate_state(model, q)
    try:
        tip = model.link(POLE_TIP)
    except KeyError:
        raise StateError(f"model {model.name!r} has no {POLE_TIP!r} sphere: no mouse-pole "
                         "height") from None
    T = forward_kinematics(model, Q).T_world_shape  # (N, F, 4, 4)
    pole = np.empty((T.shape[0], 3))
    pole[:, :2] = T[:, palm_row(model), :2, 3]
    pole[:, 2] = T[:, tip.row, 2, 3] - tip.radius
    return pole if Q.ndim == 2 else pole[0]


def buttons_from_state(model: KinematicModel, q: np.ndarray, *,
                       threshold_deg: float = DEFAULT_BUTTON_THRESHOLD_DEG
                       ) -> dict[str, np.ndarray | bool]:
    """Button states of hand state(s) ``q``: pressed when the digit is abducted further
    than ``threshold_deg`` (degrees) from its rest.

    Returns ``{"thumb": ..., "little": ...}``, each a bool for one state or a (N,) bool
    array for a batch. Raises :class:`StateError` when the model lacks ``thumb.abd`` or
    ``little.abd`` (the mouse-hand model has both).
    """
    Q = validate_state(model, q)
    threshold = np.radians(float(threshold_deg))
    pressed: dict[str, np.ndarray | bool] = {}
    for button, state in BUTTONS.items():
        if state not in model.state_names:
            raise StateError(f"model {model.name!r} has no state {state!r} for the "
                             f"{button} button")
        angles = Q[..., model.state_index(state)]
        pressed[button] = angles > threshold if Q.ndim == 2 else bool(angles > threshold)
    return pressed


@dataclass(frozen=True)
class TableMouse:
    """:func:`pole_from_state` and :func:`buttons_from_state` of one model as an object,
    the interface the mouse stream maps states through (as
    :class:`~digiteyes.apps.palm_mouse.PalmMouse` for a full hand)."""

    model: KinematicModel
    threshold_deg: float = DEFAULT_BUTTON_THRESHOLD_DEG

    def pole(self, q: np.ndarray) -> np.ndarray:
        """:func:`pole_from_state` of ``q``."""
        return pole_from_state(self.model, q)

    def buttons(self, q: np.ndarray) -> dict[str, np.ndarray | bool]:
        """:func:`buttons_from_state` of ``q`` at ``threshold_deg``."""
        return buttons_from_state(self.model, q, threshold_deg=self.threshold_deg)


def plot_mouse_pole(t: np.ndarray, pole: np.ndarray, true_pole: np.ndarray | None = None, *,
                    phases: Sequence[Sequence[float]] | None = None, xlabel: str = "frame",
                    title: str = "") -> Figure:
    """Pole base x, base y and height over time, estimate solid and truth dashed, in the
    style of thesis Fig. 4.12 (right): one panel each, millimetres.

    ``pole`` and ``true_pole`` are (T, 3) from :func:`pole_from_state`; ``phases`` a list
    of ``(first, last, ...)`` frame ranges (the ``mouse`` scenario's metadata) marked by
    dotted lines at their starts.
    """
    t = np.asarray(t, dtype=float)
    pole = np.asarray(pole, dtype=float)
    fig = new_figure(8.0, 6.5)
    fig.subplots_adjust(left=0.1, right=0.98, bottom=0.08, top=0.93, hspace=0.12)
    axes = fig.subplots(3, 1, sharex=True, squeeze=False)[:, 0]
    labels = ("pole x (mm)", "pole y (mm)", "pole height (mm)")
    for j, (ax, label) in enumerate(zip(axes, labels, strict=True)):
        ax.plot(t, pole[:, j], color=f"C{j}", label="estimate", **ESTIMATE_STYLE)
        if true_pole is not None:
            ax.plot(t, np.asarray(true_pole, dtype=float)[:, j], color="k", label="truth",
                    **TRUTH_STYLE)
        for phase in phases or ():
            ax.axvline(phase[0], color="0.5", linestyle=":", linewidth=0.8)
        ax.set_ylabel(label)
        ax.grid(alpha=0.3)
    axes[0].legend(fontsize="small", loc="upper left")
    axes[-1].set_xlabel(xlabel)
    fig.suptitle(title or "Mouse pole: estimate (solid), truth (dashed)")
    return fig


def write_mouse_pole_plot(path: str | Path, t: np.ndarray, pole: np.ndarray,
                          true_pole: np.ndarray | None = None, **kwargs) -> Path:
    """:func:`plot_mouse_pole` written as a PNG at ``path``; returns the path."""
    return save_figure(plot_mouse_pole(t, pole, true_pole, **kwargs), path)
