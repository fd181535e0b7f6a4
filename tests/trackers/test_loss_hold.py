"""The loss hold: a frame after a loss stays lost until the rules have passed the set
number of frames in a row; a reset clears it; the trackers report it without acting on
it."""

import numpy as np
import pytest

from digiteyes.camera import Rig
from digiteyes.errors import DigitEyesError
from digiteyes.synth.scenarios import build_scenario
from digiteyes.trackers import TrackResult, create_tracker
from digiteyes.trackers.loss_hold import LossHold


def _result(lost: bool) -> TrackResult:
    return TrackResult(state=np.zeros(3), cost=0.0, residual_rms_px=1.0, lost=lost,
                       loss_reason="rule fired" if lost else "", iterations=1)


def _run(hold: LossHold, rules: str) -> str:
    return "".join("1" if hold.apply(_result(c == "1")).lost else "0" for c in rules)


def test_hold_keeps_the_flag_until_enough_frames_pass():
    assert _run(LossHold(3), "0010000000") == "0011110000"
    # a loss inside the hold starts it again
    assert _run(LossHold(3), "0010100000") == "0011111100"
    assert _run(LossHold(0), "0010100000") == "0010100000"


def test_held_frames_say_so_and_keep_everything_else():
    hold = LossHold(2)
    hold.apply(_result(True))
    held = hold.apply(_result(False))
    assert held.lost and held.loss_reason == "held: 1 of 2 frames passed since the last loss"
    assert held.residual_rms_px == 1.0 and held.iterations == 1


def test_reset_clears_the_hold():
    hold = LossHold(5)
    _run(hold, "1")
    hold.reset()
    assert _run(hold, "000") == "000"


@pytest.mark.parametrize("bad", [-1, 1.5, True, "3"])
def test_bad_counts_are_refused(bad):
    with pytest.raises(DigitEyesError, match="hold_lost_frames"):
        LossHold(bad)


@pytest.mark.parametrize("name", ["features", "templates", "divide-conquer"])
def test_trackers_take_the_setting(name):
    scenario = build_scenario("desk-1cam", seed=0, n_frames=1)
    model, rig = scenario.model, Rig(scenario.rig.cameras[:1])
    assert create_tracker(name, model, rig).loss_hold.frames == 0  # no hold by default
    assert create_tracker(name, model, rig, hold_lost_frames=4).loss_hold.frames == 4


def test_a_frame_whose_finger_search_moved_a_digit_ends_the_hold():
    """After the silhouette finger search has placed the lost digits, the hold starts
    afresh (the placed digits stay flagged until seen: FingerRecovery.judge)."""
    from digiteyes.trackers.finger_search import FingerRecovery, FingerSearchOptions

    recovery = FingerRecovery(None, None, FingerSearchOptions())
    hold = LossHold(3)
    assert hold.apply(_result(True)).lost
    assert recovery.hold(hold, _result(True), searched=True).lost  # this frame is as found
    assert not hold.apply(_result(False)).lost  # no hold after it
    assert hold.apply(_result(True)).lost
    assert recovery.hold(hold, _result(False), searched=False).lost  # held as before
