"""Synthetic scenarios: a model, a camera rig and a ground-truth motion, deterministic by seed.

Each scenario re-creates one experiment of the thesis (or of Huang, Wu & Lin) as a motion
script, so that every tracker can be run against known truth (docs/scenarios.md):

``whole-hand``            thesis Sec. 4.3.3, Figs. 4.5-4.8: 27-DOF hand, two cameras.
``mouse``                 thesis Sec. 4.3.4-4.3.5, Figs. 4.10-4.12: the 3D-mouse hand.
``two-finger-occlusion``  thesis Sec. 4.4.2, Figs. 4.14-4.16: index curls past the middle.
``natural``               Huang, Wu & Lin Sec. 2: straight paths between 28 basis poses.
``fast``                  the whole-hand motion, ever faster: image speed 2 -> 36 px/frame.

World frame: the tabletop, origin on the table, z up, millimetres. Palm frame of the models:
fingers along +y, index finger on +x, palmar side +z; a hand held palm-down therefore has
palm +z along world -z.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from itertools import product

import numpy as np

from digiteyes.camera import Camera, Rig
from digiteyes.errors import DigitEyesError
from digiteyes.kinematics import KinematicModel, load_model
from digiteyes.kinematics.forward import forward_kinematics
from digiteyes.render.motion import (
    image_speed,
    joint_points,
    keyframe_path,
    palm_quaternions,
    random_key_times,
    random_keyframe_path,
)

DEG = np.pi / 180.0
HAND_CENTRE_PALM = np.array([0.0, 46.0, 0.0])
"""Middle of the full hand in its palm frame (wrist edge y = -48 mm, middle tip y = 142 mm)."""

R_PALM_DOWN = np.diag([1.0, -1.0, -1.0]) @ np.diag([-1.0, -1.0, 1.0])
"""World-from-palm rotation of a right hand lying palm-down with the fingers along world
+y: palm x -> world -x (the thumb on the user's left), y -> +y, z (palmar) -> world -z."""

SPREAD = {"index": -12.0, "middle": -3.0, "ring": 6.0, "little": 16.0}
"""Abduction (degrees) of fingers held apart, so that neighbours do not touch (positive
turns a finger towards the little-finger side, docs/models.md)."""

FINGERS = ("index", "middle", "ring", "little")


@dataclass(frozen=True)
class Scenario:
    """A synthetic sequence: model, cameras and the true state of every frame.

    Attributes
    ----------
    name, description : what the scenario is called and shows.
    model : the tracking model (the nominal model file). The images may be rendered from a
        perturbed copy (``perturb_model``) while ``states`` stay the same numbers.
    rig : the cameras (world = tabletop, z up, mm).
    states : (T, n_q) ground-truth states, one per frame.
    fps : frames per second.
    seed : the seed that made the random parts of the motion.
    metadata : JSON-ready facts about the motion (thesis section, phases, per-frame image
        speed in px/frame, ...); see docs/scenarios.md.
    """

    name: str
    description: str
    model: KinematicModel
    rig: Rig
    states: np.ndarray
    fps: float
    seed: int
    metadata: dict = field(default_factory=dict)

    @property
    def initial_state(self) -> np.ndarray:
        """The true state of frame 0 (what a tracker is initialised with)."""
        return self.states[0].copy()

    @property
    def n_frames(self) -> int:
        return len(self.states)


# --------------------------------------------------------------------------- cameras
def tabletop_camera(name: str, target: np.ndarray, distance: float, azimuth_deg: float,
                    elevation_deg: float = 45.0, focal_px: float = 800.0, width: int = 640,
                    height: int = 480) -> Camera:
    """A camera ``distance`` mm from ``target`` (world mm), looking at it.

    ``azimuth_deg`` is measured in the table plane from world +y (in front of the
    fingertips of a hand pointing along +y) towards +x; ``elevation_deg`` is the angle of
    the optical axis to the table. Image up is world up.
    """
    az, el = azimuth_deg * DEG, elevation_deg * DEG
    direction = np.array([np.cos(el) * np.sin(az), np.cos(el) * np.cos(az), np.sin(el)])
    return Camera.look_at(name, np.asarray(target, dtype=float) + distance * direction,
                          target, width=width, height=height, focal_px=focal_px)


def stereo_rig(target: np.ndarray, distance: float = 550.0, baseline: float = 450.0,
               elevation_deg: float = 45.0) -> Rig:
    """Two cameras ``baseline`` mm apart, each ``distance`` mm from ``target``, optical axes
    ``elevation_deg`` to the table, symmetric about the world y-z plane (thesis Sec. 4.3.3:
    1.5 ft apart, verging on the hand, 45 degrees to the table)."""
    half_az = np.degrees(np.arcsin(baseline / 2 / (distance * np.cos(elevation_deg * DEG))))
    return Rig((tabletop_camera("cam0", target, distance, -half_az, elevation_deg),
                tabletop_camera("cam1", target, distance, half_az, elevation_deg)))


