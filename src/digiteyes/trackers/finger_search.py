"""Silhouette finger search: bring back a digit that a local tracker has lost, by trying
it at a few curls and keeping the one that explains the hand's silhouette best.

A tracker that refines the previous estimate cannot find a finger that curled out of
sight and opens again: while it was hidden its templates or edges saw nothing, and the
estimate stayed curled. The silhouette does see it, as foreground the model does not
cover (:mod:`digiteyes.trackers.silhouette_loss`). So, on a frame the silhouette rule
calls lost, every digit is set to a few points of its path from fully extended to fully
curled (the basis configurations of Huang Sec. 2, one digit at a time; a finger's
abduction once kept and once from the path), the other digits held, and all candidates
are scored by the symmetric difference of the two silhouettes
(:meth:`~digiteyes.trackers.silhouette_loss.SilhouetteLoss.mismatches`, ``symmetric``;
a finger hidden behind the palm does not drop out of it). The single best
move is kept when it lowers the mismatch by more than ``margin``, and the search is
repeated from there (``rounds`` times at most). Taking the best move over all digits,
not the first digit that improves, matters: neighbouring fingers overlap in the
silhouette, and a wrong neighbour extended over an opening finger's pixels explains some
of them too. This is the counterpart, scored by the
silhouette instead of edges, of the divide-and-conquer tracker's digit search
(:mod:`digiteyes.smc.digit_search`); it needs what the silhouette rule needs, a plain
backdrop and a static camera, and does nothing otherwise.

The silhouette cannot say where a hidden finger is: a digit the search has curled behind
the palm fits it at any hidden curl. :class:`FingerRecovery` therefore keeps such a digit
flagged, and the frame lost, until the silhouette rule passes it and its end shows
again.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, replace

import numpy as np

from digiteyes.kinematics import KinematicModel
from digiteyes.kinematics.anatomy import DIGITS, digit_joint_angles, joint_type_of
from digiteyes.trackers.base import TrackResult
from digiteyes.trackers.loss_hold import LossHold
from digiteyes.trackers.silhouette_loss import SilhouetteLoss, SilhouetteVerdict


@dataclass(frozen=True)
class FingerSearchOptions:
    """The silhouette finger search's settings, inherited by the options of the trackers
    that use it.

    finger_search : search every digit on frames the silhouette rule calls lost. Off by
        default: the search finds states that explain the silhouette but are often still
        wrong in depth (one view cannot tell a finger bent towards the camera from one
        bent away), and then the silhouette rule, the loss flag's best witness, falls
        silent while the track is truly lost (docs/templates.md measures both).
    hidden_finger_search : search only the digits the silhouette rule's hidden-digit test
        names (hidden by the estimate while the image shows them where they would lie
        open), on the frames it names them. Off by default: over the accuracy table it
        lowers the feature and template trackers' mean fingertip error by 1-6 mm, but the
        loss flag's precision over all trackers on the flesh hand falls to 79 % (target
        80; docs/accuracy.md).
    named_finger_search : search the digits the silhouette rule names on each frame: those
        it flags (drawn over the backdrop) and those of its hidden-digit test; with the
        rule's ``judge_curled_digits`` also a digit held curled in view while the image
        shows it open. Off by default: on the desk pair it keeps every frame within 30 mm
        (issue 14's target), but the digits it places out of sight stay flagged until
        seen, and the loss flag's precision on those rows falls (``bench templates``,
        docs/templates.md).
    finger_search_levels : curls tried per digit, evenly from fully extended (0) to fully
        curled (1).
    finger_search_margin : a digit's new curl is kept only if it lowers the symmetric
        silhouette difference (hand pixels the model leaves unexplained plus model pixels
        over the backdrop, per model pixel, summed over the cameras) by more than this.
    """

    finger_search: bool = False
    hidden_finger_search: bool = False
    named_finger_search: bool = False
    finger_search_levels: int = 5
    finger_search_margin: float = 0.02

    def __post_init__(self) -> None:
        levels = self.finger_search_levels
        if isinstance(levels, bool) or not isinstance(levels, int) or levels < 2:
            raise ValueError(f"finger_search_levels must be an integer of at least 2, got "
                             f"{levels!r}")
        if not self.finger_search_margin >= 0:
            raise ValueError(f"finger_search_margin must not be negative, got "
                             f"{self.finger_search_margin!r}")


def digit_curl_paths(model: KinematicModel) -> dict[str, tuple[np.ndarray, np.ndarray,
                                                                  np.ndarray, np.ndarray]]:
    """Per digit of ``model``: (state indices, extended angles, curled angles, flexion
    mask) of its joints, rad; the mask is False for a finger's abduction."""
    names = set(model.state_names)
    paths = {}
    for digit in DIGITS:
        extended = digit_joint_angles(digit, extended=True)
        curled = digit_joint_angles(digit, extended=False)
        joints = [j for j in extended if j in names]
        if joints:
            paths[digit] = (np.array([model.state_index(j) for j in joints]),
                            np.array([extended[j] for j in joints]),
                            np.array([curled[j] for j in joints]),
                            np.array([joint_type_of(j) != "abd" for j in joints]))
    return paths


def digit_candidates(model: KinematicModel, state: np.ndarray, levels: int
                     ) -> tuple[np.ndarray, np.ndarray]:
    """(C, n_q) states: ``state`` with one digit moved to one of ``levels`` points of its
    path from fully extended to fully curled, once with its abduction kept and once with
    the path's (a finger flipped onto its neighbour is off sideways too); and (C,) the
    position in :func:`digit_curl_paths` of the digit each candidate moves."""
    curls = np.linspace(0.0, 1.0, levels)[:, None]
    blocks, owners = [], []
    for d, (index, extended, curled, flexion) in enumerate(digit_curl_paths(model).values()):
        path = np.clip(extended + curls * (curled - extended), model.lower[index],
                       model.upper[index])
        with_path = np.repeat(state[None], levels, axis=0)
        with_path[:, index] = path
        blocks.append(with_path)
        if not flexion.all():
            kept = with_path.copy()
            kept[:, index[~flexion]] = state[index[~flexion]]
            blocks.append(kept)
        owners.append(np.full(levels if flexion.all() else 2 * levels, d))
    return np.concatenate(blocks), np.concatenate(owners)


def search_fingers(model: KinematicModel, rule: SilhouetteLoss, images: Sequence[np.ndarray],
                   state: np.ndarray, levels: int = 5, margin: float = 0.02,
                   rounds: int = 2, digits: Sequence[str] | None = None,
                   colours: Sequence[np.ndarray] | None = None
                   ) -> tuple[np.ndarray, tuple[str, ...]] | None:
    """The silhouette finger search (module docstring) from ``state`` (n_q,) in ``images``
    (one per camera, rig order; ``colours`` the frames as they came, for the rule's colour
    model), moving only ``digits`` (None: every digit): the better state and the digits
    moved, or None when no digit moved (or the rule checks no camera)."""
    current = rule.mismatches(images, [state], symmetric=True, colours=colours)
    if current is None:
        return None
    best_state, best = np.array(state, dtype=float), current[0]
    names = list(digit_curl_paths(model))
    moved: list[str] = []
    for _ in range(rounds):
        candidates, digit_of = digit_candidates(model, best_state, levels)
        if digits is not None:
            keep = np.isin(np.array(names)[digit_of], list(digits))
            if not keep.any():
                break
            candidates, digit_of = candidates[keep], digit_of[keep]
        scores = rule.mismatches(images, list(candidates), symmetric=True, colours=colours)
        k = int(np.argmin(scores))
        if not scores[k] < best - margin:
            break
        best_state, best = candidates[k], scores[k]
        moved.append(names[digit_of[k]])
    return (best_state, tuple(dict.fromkeys(moved))) if moved else None


class FingerRecovery:
    """One track's finger search and the digits it has placed that the silhouette has not
    seen since.

    A digit the search has curled out of sight satisfies the silhouette at any hidden
    curl, so a wrong one would no longer be flagged. Such a digit stays flagged (and the
    frame lost) until it is seen again: the silhouette rule passes it and its end shows
    in some camera (:meth:`~digiteyes.trackers.silhouette_loss.SilhouetteLoss.end_shown`;
    a digit of which only the base shows says nothing of where its tip is).
    """

    def __init__(self, model: KinematicModel, rule: SilhouetteLoss,
                 options: FingerSearchOptions) -> None:
        self.model, self.rule, self.options = model, rule, options
        self.unseen: list[str] = []

    def reset(self) -> None:
        """Forget the placed digits (a new track)."""
        self.unseen = []

    def digits_to_search(self, verdict: SilhouetteVerdict) -> list[str]:
        """The digits to search after ``verdict``: every digit of the model when
        ``finger_search`` is on and the frame is lost, the digits it flags and those of
        its hidden-digit test when ``named_finger_search`` is on, the latter alone when
        ``hidden_finger_search`` is on, else none."""
        if self.options.finger_search and verdict.reasons:
            return list(digit_curl_paths(self.model))
        if self.options.named_finger_search:
            flagged = [d for d, lost in verdict.finger_lost.items() if lost]
            return list(dict.fromkeys([*verdict.hidden_shown, *flagged]))
        if self.options.hidden_finger_search:
            return list(verdict.hidden_shown)
        return []

    def improves(self, images: Sequence[np.ndarray], state: np.ndarray,
                 found: np.ndarray, colours: Sequence[np.ndarray] | None = None) -> bool:
        """Whether ``found`` (the solve from a search's result) explains the hand's
        silhouette in ``images`` (``colours``: the frames as they came) better than
        ``state`` (the symmetric difference): the test a tracker's re-solve must pass to
        replace its first estimate."""
        before, after = self.rule.mismatches(images, [state, found], symmetric=True,
                                             colours=colours)
        return after < before

    def search(self, images: Sequence[np.ndarray], state: np.ndarray,
               digits: Sequence[str] | None = None,
               colours: Sequence[np.ndarray] | None = None
               ) -> tuple[np.ndarray, tuple[str, ...]] | None:
        """:func:`search_fingers` with this track's settings, moving only ``digits``
        (None: every digit)."""
        return search_fingers(self.model, self.rule, images, state,
                              self.options.finger_search_levels,
                              self.options.finger_search_margin, digits=digits,
                              colours=colours)

    def hold(self, loss_hold: LossHold, result: TrackResult, searched: bool) -> TrackResult:
        """``result`` through the track's :class:`~digiteyes.trackers.loss_hold.LossHold`;
        after a frame whose search moved a digit the hold starts afresh: the hold keeps a
        local tracker's loss because it rarely finds a lost finger by itself, and here the
        search has placed it; the placed digits stay flagged until seen (:meth:`judge`)."""
        reported = loss_hold.apply(result)
        if searched:
            loss_hold.reset()
        return reported

    def placed(self, digits: Sequence[str]) -> None:
        """Record ``digits`` as placed by the search (in the frame being judged)."""
        self.unseen = list(dict.fromkeys([*self.unseen, *digits]))

    def judge(self, verdict: SilhouetteVerdict) -> SilhouetteVerdict:
        """``verdict`` with every placed digit the verdict does not see and pass flagged,
        and a reason naming them; placed digits it sees and passes are let go."""
        self.unseen = [d for d in self.unseen
                       if verdict.finger_lost.get(d, True)
                       or not self.rule.end_shown(d, verdict.checks)]
        if not self.unseen:
            return verdict
        fingers = {**verdict.finger_lost, **dict.fromkeys(self.unseen, True)}
        reason = (f"placed by the finger search and not seen since: "
                  f"{', '.join(self.unseen)}")
        return replace(verdict, reasons=[*verdict.reasons, reason], finger_lost=fingers)
