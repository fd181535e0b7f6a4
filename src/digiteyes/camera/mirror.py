"""Left hands through a right-hand model: track the mirror image of the scene.

A left hand is the mirror image of a right hand, and a mirror is not a rigid motion, so no
state of a right-hand model (palm quaternion, joint angles) poses a left hand. Its mirror
image is a right hand, though. Reflect the world in its y-z plane, ``P' = S P`` with
``S = diag(-1, 1, 1)``; a camera ``T_cam_world = [R | t]`` becomes ``[S R S | S t]``, so
the point in the camera frame becomes ``S X_cam``: its image column ``u`` becomes
``W - 1 - u`` (pixel centres at integer coordinates) when the principal point moves from
``cx`` to ``W - 1 - cx`` and the skew and the tangential coefficient ``p2`` (OpenCV's x
term) change sign; the radial terms and ``p1`` stay. Flipping every image left to right
and using the mirrored rig is therefore exactly the reflected scene, one camera or many:
a left hand there is a right hand, tracked by the right-hand model; joint angles are the
same in both worlds, and points come back with :func:`unmirror_pixels` and
:func:`unmirror_points`.

``Rig.mirrored`` marks a rig made by :func:`mirrored_rig` (so keypoint outputs and
overlays are turned back); mirroring twice gives the rig back.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from digiteyes.camera.camera import Camera
from digiteyes.camera.reflection import REFLECTION, unmirror_pixels, unmirror_points
from digiteyes.camera.rig import Rig

__all__ = ["HANDS", "REFLECTION", "mirror_images", "mirrored_camera", "mirrored_rig",
           "rig_for_hand", "unmirror_pixels", "unmirror_points"]

HANDS = ("right", "left")
"""Values of ``--hand``: the side of the hand in the images."""

_S4 = np.diag([*REFLECTION, 1.0])


def mirrored_camera(camera: Camera) -> Camera:
    """The camera that sees the reflected world ``S P`` as ``camera`` sees ``P``, with its
    images flipped left to right (module docstring)."""
    K = np.array(camera.K, dtype=float)
    K[0, 2] = camera.width - 1 - K[0, 2]
    K[0, 1] = -K[0, 1]
    dist = np.array(camera.dist, dtype=float)
    dist[3] = -dist[3]
    return Camera.create(camera.name, K, camera.width, camera.height,
                         _S4 @ camera.T_cam_world @ _S4, dist, camera.projection,
                         camera.depth_mm)


def mirrored_rig(rig: Rig) -> Rig:
    """Every camera mirrored (:func:`mirrored_camera`); ``mirrored`` toggled."""
    return Rig(tuple(mirrored_camera(c) for c in rig), mirrored=not rig.mirrored,
               real_sizes=rig.real_sizes)


def rig_for_hand(rig: Rig, hand: str) -> Rig:
    """The rig a right-hand model tracks ``hand`` (``"right"`` or ``"left"``) through."""
    if hand not in HANDS:
        raise ValueError(f"hand must be one of {', '.join(HANDS)}, got {hand!r}")
    return mirrored_rig(rig) if hand == "left" else rig


def mirror_images(images: Sequence[np.ndarray]) -> list[np.ndarray]:
    """Each image flipped left to right (a contiguous copy)."""
    return [np.ascontiguousarray(np.asarray(image)[:, ::-1]) for image in images]
