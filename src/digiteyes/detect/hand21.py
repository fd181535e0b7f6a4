"""The 21 hand keypoints every detector reports, and where they sit on a kinematic model.

Order (the common one of MediaPipe Hands, FreiHAND and InterHand): 0 the wrist, then per
digit four points from the base to the tip: thumb 1-4 (CMC, MCP, IP, tip), index 5-8,
middle 9-12, ring 13-16, little 17-20 (MCP, PIP, DIP, tip).

On the shipped hand model (``hand.dh``, Rehg Appendix A) a digit's joints are the bases of
its links (the joint centres at the start of each cylinder axis); a tip is the end of the
finger (the tip sphere's centre moved along the distal axis by the end radius, as
annotators mark it); the wrist is the middle of the palm slab's proximal end face.
"""

from __future__ import annotations

import numpy as np

from digiteyes.errors import DigitEyesError
from digiteyes.kinematics import KinematicModel

DIGITS = ("thumb", "index", "middle", "ring", "little")
_THUMB_PARTS = ("cmc", "mcp", "ip", "tip")
_FINGER_PARTS = ("mcp", "pip", "dip", "tip")
HAND21_NAMES: tuple[str, ...] = (
    "wrist",
    *(f"thumb.{p}" for p in _THUMB_PARTS),
    *(f"{d}.{p}" for d in DIGITS[1:] for p in _FINGER_PARTS),
)
"""Names of the 21 keypoints, in order."""
TIPS = (4, 8, 12, 16, 20)
"""Indices of the five fingertips (thumb to little)."""
PALM_FIXED = (0, 1, 5, 9, 13, 17)
"""Keypoints fixed in the palm frame of the model (wrist, thumb CMC, four MCPs): a rigid
palm pose aligns them."""
PALM = (0, 5, 9, 13, 17)
"""The wrist and the four finger MCPs: coplanar in the model's palm frame, rigid, and
placed alike by a detector and the model (the fingers' keypoints sit by each detector's
convention)."""
DIGIT_KEYPOINTS = {digit: [1 + 4 * d + k for k in range(4)] for d, digit in enumerate(DIGITS)}
"""Each digit's four keypoints (base to tip)."""
BONES = tuple((0 if k % 4 == 1 else k - 1, k) for k in range(1, 21))
"""Parent-child pairs (20) for drawing skeletons."""

_LINKS = {"thumb": ("thumb.metacarpal", "thumb.proximal", "thumb.distal", "thumb.tip")}
_LINKS.update({d: (f"{d}.proximal", f"{d}.middle", f"{d}.distal", f"{d}.tip")
               for d in DIGITS[1:]})


def model_anchors(model: KinematicModel) -> tuple[np.ndarray, np.ndarray]:
    """Shape-frame rows (21,) and points (21, 3) mm of the 21 keypoints on ``model``.

    Raises :class:`DigitEyesError` when the model lacks a palm or one of the digit links
    (the shipped ``hand`` model has them all).
    """
    names = {link.name: link for link in model.links}
    palm = next((link for link in model.links if link.kind == "palm"), None)
    if palm is None:
        raise DigitEyesError(f"model {model.name!r} has no palm: the 21 hand keypoints need "
                             "the full hand model")
    wrist = np.asarray(palm.centre, dtype=float) - (0.0, 0.5 * palm.size[1], 0.0)
    rows, points = [palm.row], [wrist]
    for digit in DIGITS:
        for part in _LINKS[digit]:
            link = names.get(part)
            if link is None:
                raise DigitEyesError(f"model {model.name!r} has no link {part!r}: the 21 hand "
                                     "keypoints need the full hand model")
            rows.append(link.row)
            if link.kind == "tip":
                distal = names[part.replace(".tip", ".distal")]
                points.append(np.array([max(link.radius, distal.radius), 0.0, 0.0]))
            else:
                points.append(np.zeros(3))
    return np.array(rows, dtype=np.int64), np.array(points, dtype=float)
