"""The silhouette finger search: candidates move one digit along its curl; the search
brings back a finger the estimate has wrong (on images of the independent flesh hand) and
leaves a right state alone; the trackers use it, when asked, on frames the silhouette
rule calls lost."""

import numpy as np
import pytest

from digiteyes.kinematics import forward_kinematics
from digiteyes.kinematics.anatomy import DIGITS
from digiteyes.synth import RenderOptions, render_views
from digiteyes.trackers import TrackerError, create_tracker
from digiteyes.trackers.finger_search import digit_candidates, search_fingers
from digiteyes.trackers.silhouette_loss import SilhouetteLoss


def _index_tip_error(model, a, b) -> float:
    row = next(link.row for link in model.links if link.name == "index.tip")
    ta = forward_kinematics(model, a).T_world_shape[0, row, :3, 3]
    tb = forward_kinematics(model, b).T_world_shape[0, row, :3, 3]
    return float(np.linalg.norm(ta - tb))


def test_candidates_move_one_digit_along_its_curl(desk):
    model, _, q, *_ = desk
    candidates, owners = digit_candidates(model, q, levels=5)
    # four fingers with abduction kept and from the path, the thumb once: 9 blocks of 5
    assert candidates.shape == (45, model.n_q) and owners.shape == (45,)
    digit_of = np.array([name.split(".")[0] for name in model.state_names])
    for candidate, owner in zip(candidates, owners, strict=True):
        moved = set(digit_of[~np.isclose(candidate, q)])
        assert len(moved) <= 1 and moved <= set(DIGITS)
        assert moved <= {DIGITS[owner]}
    assert np.all(candidates >= model.lower - 1e-12) and np.all(candidates <= model.upper + 1e-12)
    pip = model.state_index("index.pip")
    assert {round(float(np.degrees(v))) for v in candidates[:, pip]} >= {0, 95}


def test_search_brings_back_the_finger_and_leaves_a_right_state(desk):
    model, rig, q, curled, image, image_curled = desk
    rule = SilhouetteLoss(model, rig)
    assert search_fingers(model, rule, [image], curled) is None  # no foreground fitted yet
    rule.check([image], q, q)
    # the estimate curls the index, the hand holds it straight
    found, moved = search_fingers(model, rule, [image], curled)
    assert moved == ("index",)
    assert _index_tip_error(model, curled, q) > 60.0
    assert _index_tip_error(model, found, q) < 25.0
    before, after = rule.mismatches([image], [curled, found], symmetric=True)
    assert after < before - 0.05
    # the estimate holds the index straight, the hand has curled it (seen from above, a
    # half and a full curl hide behind the hand alike: the search curls it at least half)
    found, moved = search_fingers(model, rule, [image_curled], q)
    assert moved == ("index",)
    assert found[model.state_index("index.pip")] > np.radians(40.0)
    # a right state stays
    assert search_fingers(model, rule, [image], q) is None


def test_symmetric_mismatch_counts_a_hidden_finger(desk):
    """The curled index hides behind the palm: the finger mean of ``mismatch`` drops it,
    the symmetric difference leaves the real finger's pixels unexplained."""
    model, rig, q, curled, image, _ = desk
    rule = SilhouetteLoss(model, rig)
    rule.check([image], q, q)
    right, hidden = rule.mismatches([image], [q, curled], symmetric=True)
    assert hidden > right + 0.05


@pytest.mark.parametrize("tracker", ["templates", "templates+features", "features"])
def test_trackers_search_the_fingers_on_a_lost_frame(desk, tracker):
    """The hand opens its curled index and middle fingers in one frame, far beyond any
    local step: the template trackers follow it with the finger search (and the frame
    is not lost), the feature tracker halves the error (the index, 60 mm off, stays
    flagged), and all lose both fingers without it."""
    model, rig, q, _, image, _ = desk
    curled = q.copy()
    for finger in ("index", "middle"):
        for joint, angle in zip(("mcp", "pip", "dip"), (80.0, 95.0, 60.0), strict=True):
            curled[model.state_index(f"{finger}.{joint}")] = np.radians(angle)
    image_curled = render_views(model, curled, rig,
                                RenderOptions(appearance="flesh", noise_sigma=2.0), rng=1)[0].image
    rows = [next(link.row for link in model.links if link.name == f"{finger}.tip")
            for finger in ("index", "middle")]
    truth = forward_kinematics(model, q).T_world_shape[0, rows, :3, 3]
    errors = {}
    for search in (True, False):
        runner = create_tracker(tracker, model, rig, finger_search=search)
        runner.reset(curled)
        first = runner.step([image_curled])
        assert not first.lost and not first.details.searched
        second = runner.step([image])
        assert second.details.searched is search
        if tracker.startswith("templates"):
            assert second.lost is not search, second.loss_reason
        else:
            assert second.lost
        tips = forward_kinematics(model, second.state).T_world_shape[0, rows, :3, 3]
        errors[search] = np.linalg.norm(tips - truth, axis=1)
    assert errors[False].min() > 60.0, errors
    if tracker.startswith("templates"):
        assert errors[True].max() < 25.0, errors
    else:  # the feature tracker's edges pull the index part of the way back: still lost
        assert errors[True].max() < 0.5 * errors[False].min(), errors


def test_a_placed_finger_stays_flagged_until_the_silhouette_sees_it(desk):
    """The search curls the index out of sight (the hand has curled it): the silhouette
    is satisfied, but where a hidden finger lies it cannot say, so the finger stays
    flagged; once the hand opens it and the silhouette sees it in place, it is let go."""
    from digiteyes.trackers.finger_search import FingerRecovery, FingerSearchOptions

    model, rig, q, _, image, image_curled = desk
    rule = SilhouetteLoss(model, rig)
    rule.check([image], q, q)
    recovery = FingerRecovery(model, rule, FingerSearchOptions())
    found, moved = recovery.search([image_curled], q)
    recovery.placed(moved)
    verdict = recovery.judge(rule.check([image_curled], found, q))
    assert verdict.finger_lost["index"]
    assert any("not seen since: index" in r for r in verdict.reasons)
    assert not any(v for k, v in verdict.finger_lost.items() if k != "index")
    # the hand opens the finger again and the estimate follows it
    verdict = recovery.judge(rule.check([image], q, q))
    assert not verdict.reasons and not any(verdict.finger_lost.values())
    assert recovery.unseen == []


@pytest.mark.parametrize(("key", "value"), [("finger_search_levels", 1),
                                            ("finger_search_margin", -0.1)])
def test_bad_search_options_are_refused(desk, key, value):
    model, rig, *_ = desk
    with pytest.raises(TrackerError, match=key):
        create_tracker("templates", model, rig, **{key: value})


def test_the_hidden_digit_test_names_the_digits_to_search(desk):
    """The estimate has curled the index under the palm while the hand holds it straight:
    the rule's hidden-digit test names it, and with ``hidden_finger_search`` only it is
    searched; with ``finger_search`` every digit is, and with both off (the default) none
    is."""
    from digiteyes.trackers.finger_search import FingerRecovery, FingerSearchOptions

    model, rig, q, curled, image, _ = desk
    rule = SilhouetteLoss(model, rig)
    rule.check([image], q, q)
    verdict = rule.check([image], curled, q)
    assert verdict.hidden_shown == ("index",)
    assert rule.check([image], q, q).hidden_shown == ()
    hidden = FingerRecovery(model, rule, FingerSearchOptions(hidden_finger_search=True))
    assert hidden.digits_to_search(verdict) == ["index"]
    assert FingerRecovery(model, rule, FingerSearchOptions(
        finger_search=True)).digits_to_search(verdict) == list(DIGITS)
    assert FingerRecovery(model, rule, FingerSearchOptions()).digits_to_search(verdict) == []
    found, moved = hidden.search([image], curled, ["index"])
    assert moved == ("index",) and _index_tip_error(model, found, q) < 25.0
    assert hidden.improves([image], curled, found) and not hidden.improves([image], found,
                                                                          curled)
    assert search_fingers(model, rule, [image], curled, digits=["thumb"]) is None


@pytest.mark.parametrize("tracker", ["templates", "features"])
def test_trackers_open_a_finger_they_hid_while_the_hand_shows_it(desk, tracker):
    """The track has curled the index under the palm (set here by hand) while the hand
    holds it straight: with the hidden-digit search (opt-in) the next frame opens
    it and reports the found state, which the rules pass; without it the index stays
    curled, more than 60 mm off, and the frames are lost."""
    model, rig, q, curled, image, _ = desk
    errors = {}
    for hidden_search in (True, False):
        runner = create_tracker(tracker, model, rig, hidden_finger_search=hidden_search)
        runner.reset(q)
        assert not runner.step([image]).lost
        runner.state = curled  # the estimate has lost the finger under the palm
        runner.predictor.reset(curled)
        second = runner.step([image])
        assert second.details.searched is hidden_search
        assert second.lost is not hidden_search, second.loss_reason
        errors[hidden_search] = _index_tip_error(model, second.state, q)
        third = runner.step([image])
        assert third.lost is not hidden_search, third.loss_reason
    assert errors[False] > 60.0 and errors[True] < 25.0, errors


def test_the_named_search_takes_the_digits_the_rule_flags_too(desk):
    """``named_finger_search``: the digits the rule flags (here the index drawn curled
    under the palm while the image shows it straight, and a digit drawn over the
    backdrop) are searched, as are those of the hidden-digit test; a verdict that flags
    nothing names nothing."""
    from dataclasses import replace

    from digiteyes.trackers.finger_search import FingerRecovery, FingerSearchOptions

    model, rig, q, curled, image, _ = desk
    rule = SilhouetteLoss(model, rig)
    rule.check([image], q, q)
    verdict = rule.check([image], curled, q)
    named = FingerRecovery(model, rule, FingerSearchOptions(named_finger_search=True))
    assert named.digits_to_search(verdict) == ["index"]
    off_silhouette = replace(verdict, hidden_shown=(),
                             finger_lost={**verdict.finger_lost, "index": False, "ring": True})
    assert named.digits_to_search(off_silhouette) == ["ring"]
    assert named.digits_to_search(rule.check([image], q, q)) == []
