"""Hold a track's loss flag until the track has proved itself again.

The loss rules of a tracker judge one frame at a time. A local optimiser (the feature and
template trackers) that has lost a finger rarely finds it again by itself, yet the rules
often pass it again a few frames later: the wrong pose fits the image well enough
(docs/accuracy.md). :class:`LossHold` can therefore keep a frame ``lost`` until the
rules have passed ``frames`` frames in a row after the last frame they failed; those
held frames carry the reason ``held``. A reset or a re-initialisation
(:func:`~digiteyes.trackers.restart`) clears the hold. It is off by default (an option
of every tracker): since the rules compare each frame with the start state, the frames
they pass after a loss are mostly frames the track has in fact got back.

The hold changes the reported flag only: what a tracker does with its own verdict (the
feature tracker's prediction, the template refresh) still follows the frame's rules.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

from digiteyes.errors import DigitEyesError
from digiteyes.trackers.base import TrackResult


@dataclass(frozen=True)
class LossHoldOptions:
    """The hold's setting, shared by every tracker's options class.

    hold_lost_frames : after a frame the loss rules call lost, the next frames stay lost
        until this many in a row have passed the rules (0, every tracker's default: no
        hold, each frame judged on its own; why: docs/accuracy.md, "The hold, measured
        again").
    """

    hold_lost_frames: int = 0


class LossHold:
    """The hold of one track (module docstring); ``frames`` as ``hold_lost_frames``.

    Raises :class:`~digiteyes.errors.DigitEyesError` for a negative or non-integer count.
    """

    def __init__(self, frames: int) -> None:
        if isinstance(frames, bool) or not isinstance(frames, int) or frames < 0:
            raise DigitEyesError(f"hold_lost_frames must be an integer >= 0, got {frames!r}")
        self.frames = frames
        self.reset()

    def reset(self) -> None:
        """Forget past losses (a new track, or a re-initialised one)."""
        self._passed: int | None = None

    def apply(self, result: TrackResult) -> TrackResult:
        """``result`` as reported: unchanged when its rules failed or no hold is due,
        otherwise marked lost with the reason ``held``."""
        if result.lost:
            self._passed = 0
            return result
        if self._passed is None or self._passed >= self.frames:
            return result
        self._passed += 1
        return replace(result, lost=True, loss_reason=(
            f"held: {self._passed} of {self.frames} frames passed since the last loss"))
