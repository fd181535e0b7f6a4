"""Applications built on the trackers' state estimates.

:mod:`digiteyes.apps.mouse3d` is the 3D mouse of thesis Sec. 4.3.4: the palm position on
the table moves the base of a "mouse pole" cursor, the index fingertip's height sets the
pole's height, and the thumb and little finger are buttons (docs/mouse3d.md).
:mod:`digiteyes.apps.palm_mouse` gives the same controls from a full hand seen from any
camera, measured against the hand's own start pose (a webcam, no table calibration).
"""

from digiteyes.apps.mouse3d import (
    BUTTONS,
    DEFAULT_BUTTON_THRESHOLD_DEG,
    TableMouse,
    buttons_from_state,
    plot_mouse_pole,
    pole_from_state,
    write_mouse_pole_plot,
)
from digiteyes.apps.palm_mouse import PalmMouse

__all__ = [
    "BUTTONS", "DEFAULT_BUTTON_THRESHOLD_DEG", "PalmMouse", "TableMouse",
    "buttons_from_state", "plot_mouse_pole", "pole_from_state", "write_mouse_pole_plot",
]
