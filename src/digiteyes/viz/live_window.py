"""``digiteyes track --show``: the overlay of each tracked frame in a window (OpenCV).

Without a display (no ``DISPLAY`` or ``WAYLAND_DISPLAY`` on Linux) or with an OpenCV
built without a GUI, :func:`open_live_window` returns None and a message saying why; the
run goes on without the window. Pressing ``q`` or Esc in the window closes it.
"""

from __future__ import annotations

import os
import sys
from collections.abc import Sequence

import cv2
import numpy as np

from digiteyes.camera import Rig
from digiteyes.kinematics import KinematicModel
from digiteyes.trackers import TrackResult
from digiteyes.viz.track_overlay import overlay_image

WINDOW_TITLE = "digiteyes track"


def display_available() -> str | None:
    """None when a window can be shown, else the reason."""
    if sys.platform.startswith("linux") and not (os.environ.get("DISPLAY")
                                                 or os.environ.get("WAYLAND_DISPLAY")):
        return "no display (DISPLAY and WAYLAND_DISPLAY are unset)"
    return None


class LiveWindow:
    """A :class:`digiteyes.pipeline.FrameSink` drawing :func:`overlay_image` per frame."""

    def __init__(self, model: KinematicModel, rig: Rig) -> None:
        self.model = model
        self.rig = rig
        self.open = True

    def write(self, index: int, images: Sequence[np.ndarray], result: TrackResult,
              reinitialised: bool) -> None:
        if not self.open:
            return
        image = overlay_image(images, result, self.rig, self.model)
        cv2.imshow(WINDOW_TITLE, cv2.cvtColor(image, cv2.COLOR_RGB2BGR))
        if cv2.waitKey(1) & 0xFF in (ord("q"), 27):
            self.close()

    def close(self) -> None:
        if self.open:
            self.open = False
            cv2.destroyWindow(WINDOW_TITLE)


def open_live_window(model: KinematicModel, rig: Rig) -> tuple[LiveWindow | None, str]:
    """The window, or None and why it cannot be shown (no display, no GUI in OpenCV)."""
    reason = display_available()
    if reason is not None:
        return None, f"--show skipped: {reason}"
    try:
        cv2.namedWindow(WINDOW_TITLE, cv2.WINDOW_NORMAL)
    except cv2.error as exc:
        return None, f"--show skipped: OpenCV cannot open a window ({str(exc).strip()[:80]})"
    return LiveWindow(model, rig), "showing the overlay (q or Esc closes the window)"
