"""The 3D mouse of thesis Sec. 4.3.4 driven by a full hand seen from anywhere (ours).

The thesis's mouse (:mod:`digiteyes.apps.mouse3d`) needs the reduced ``mouse-hand``
model and a camera calibrated in the table's frame: its pole lives in table millimetres.
A webcam user has neither. This mapping takes the full hand (``hand``, or a personal
model from ``calibrate-hand``) tracked in any world frame, e.g. the camera's, and
measures everything against the hand itself:

* **the table** is the palm's pose in the first tracked state ``q0``: origin at the palm
  frame's origin (the point ``evaluate`` scores as the palm position), x towards the
  little finger's side, y along the fingers, z out of the back of the hand. A hand lying
  palm down on a desk before a webcam has its table on the desk, x to the user's right,
  y forward, z up; a hand held up facing the camera has its table in the plane of the
  palm. (A left hand, tracked as the right hand of the mirror image,
  :mod:`digiteyes.camera.mirror`, gets x towards its thumb's side, again the user's
  right, so that the same motion moves the pole the same way.)
* **pole base** = the palm frame's origin in that table frame, x and y (mm);
* **pole height** = the index fingertip's height above the *current* palm plane, along
  the back of the hand (mm), less that height in ``q0``: 0 at the start, positive when
  the finger is raised (from a straight finger, an MCP extension of theta raises it by
  ``L sin theta``, L the MCP-to-tip length, 95 mm for Appendix A's index). Measured
  against the palm, not the table, so that the pole's height and base stay decoupled
  (thesis Sec. 4.3.4) whatever the palm does;
* **buttons** = the thumb and the little finger spread away from the fingers in the palm
  plane by more than a threshold beyond their spread in ``q0``: the angle, in the palm
  plane, of the digit's base-to-tip line from the fingers' direction. Geometric rather
  than one joint's angle, so it does not depend on how a model names or splits the
  thumb's joints, and relative to the start, so that a hand that rests with its thumb
  a little out does not hold the button down.

Everything is in millimetres and radians inside; thresholds are given in degrees.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from digiteyes.apps.mouse3d import DEFAULT_BUTTON_THRESHOLD_DEG, POLE_TIP, palm_row
from digiteyes.errors import StateError
from digiteyes.kinematics import KinematicModel, forward_kinematics, validate_state

SPREAD_LINKS = {"thumb": ("thumb.metacarpal", "thumb.tip", 1.0),
                "little": ("little.proximal", "little.tip", -1.0)}
"""Button -> (the digit's first link, its tip, the sign of the palm-frame x that points
away from the other fingers: +x is the thumb's side of the right-hand palm frame)."""


def _row(model: KinematicModel, name: str) -> int:
    try:
        return model.link(name).row
    except KeyError:
        raise StateError(f"model {model.name!r} has no link {name!r}: the palm mouse needs "
                         "a full hand (index tip, thumb, little finger)") from None


@dataclass(frozen=True)
class PalmMouse:
    """Pole and buttons of a full hand against its own start pose (module docstring).

    Attributes
    ----------
    model : the tracked full-hand model.
    T_table_world : (4, 4) from the world frame of the states to the table frame (mm);
        for a mirror image's states an orthogonal map with a reflection (the table frame
        is right-handed in the real world, so left-handed in the mirror image's).
    rest_spread : button -> the digit's spread in the start state (rad).
    rest_height : the index tip's height above the palm plane in the start state (mm).
    threshold_deg : spread beyond the rest (degrees) that presses a button.
    """

    model: KinematicModel
    T_table_world: np.ndarray
    rest_spread: dict[str, float]
    rest_height: float = 0.0
    threshold_deg: float = DEFAULT_BUTTON_THRESHOLD_DEG

    @classmethod
    def from_start(cls, model: KinematicModel, q0: np.ndarray, *, mirrored: bool = False,
                   threshold_deg: float = DEFAULT_BUTTON_THRESHOLD_DEG) -> PalmMouse:
        """The mapping whose table is the palm of state ``q0`` (n_q,); ``mirrored``: the
        states are a left hand's mirror image (x then points to the thumb's side)."""
        T = forward_kinematics(model, validate_state(model, q0)).T_world_shape[0, palm_row(model)]
        R_world_palm, origin = T[:3, :3], T[:3, 3]
        sign = 1.0 if mirrored else -1.0  # x: the little finger's side of a right hand
        R_world_table = np.column_stack([sign * R_world_palm[:, 0], R_world_palm[:, 1],
                                         -R_world_palm[:, 2]])
        T_table_world = np.eye(4)
        T_table_world[:3, :3] = R_world_table.T
        T_table_world[:3, 3] = -R_world_table.T @ origin
        mouse = cls(model, T_table_world, {}, 0.0, float(threshold_deg))
        spread = mouse.spread(q0)
        return cls(model, T_table_world, {k: float(v) for k, v in spread.items()},
                   float(mouse.pole(q0)[2]), float(threshold_deg))

    def _frames(self, q: np.ndarray) -> tuple[np.ndarray, bool]:
        Q = validate_state(self.model, q)
        T = forward_kinematics(self.model, Q).T_world_shape  # (N, F, 4, 4), N = 1 for one
        return T, Q.ndim == 2

    def pole(self, q: np.ndarray) -> np.ndarray:
        """Pole base x, base y (table mm) and height (mm above the palm plane) of state(s)
        ``q`` (n_q,) or (N, n_q): (3,) or (N, 3)."""
        T, batch = self._frames(q)
        palm = T[:, palm_row(self.model)]
        tip = T[:, _row(self.model, POLE_TIP), :3, 3]
        base = palm[:, :3, 3] @ self.T_table_world[:3, :3].T + self.T_table_world[:3, 3]
        # the tip in the palm frame; the back of the hand is the palm frame's -z
        height = -np.einsum("ni,ni->n", palm[:, :3, 2], tip - palm[:, :3, 3]) - self.rest_height
        pole = np.column_stack([base[:, :2], height])
        return pole if batch else pole[0]

    def spread(self, q: np.ndarray) -> dict[str, np.ndarray | float]:
        """Each button digit's spread (rad): the angle, in the palm plane, of its first
        link's base to its tip from the palm's y axis, positive away from the fingers."""
        T, batch = self._frames(q)
        palm = T[:, palm_row(self.model)]
        out: dict[str, np.ndarray | float] = {}
        for button, (first, end, side) in SPREAD_LINKS.items():
            line = T[:, _row(self.model, end), :3, 3] - T[:, _row(self.model, first), :3, 3]
            x = np.einsum("ni,ni->n", palm[:, :3, 0], line)
            y = np.einsum("ni,ni->n", palm[:, :3, 1], line)
            angle = np.arctan2(side * x, y)
            out[button] = angle if batch else float(angle[0])
        return out

    def buttons(self, q: np.ndarray) -> dict[str, np.ndarray | bool]:
        """Button -> pressed (bool, or (N,) bool for a batch): the digit spread more than
        ``threshold_deg`` beyond its spread at the start."""
        threshold = np.radians(self.threshold_deg)
        pressed: dict[str, np.ndarray | bool] = {}
        for button, angle in self.spread(q).items():
            over = np.asarray(angle) - self.rest_spread[button] > threshold
            pressed[button] = over if over.ndim else bool(over)
        return pressed
