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

import numpy as np
from scipy.optimize import brentq

from digiteyes.camera import Camera, Rig
from digiteyes.errors import DigitEyesError
from digiteyes.kinematics import KinematicModel, load_model
from digiteyes.kinematics.anatomy import (
    FINGERS,
    SPREAD_DEG,
    THUMB_JOINTS,
    basis_configurations,
    basis_joint_angles,
)
from digiteyes.kinematics.forward import forward_kinematics
from digiteyes.kinematics.rotations import matrix_from_quaternion
from digiteyes.synth.motion import (
    image_speed,
    keyframe_path,
    palm_quaternions,
    random_keyframe_path,
)

DEG = np.pi / 180.0
HAND_CENTRE_PALM = np.array([0.0, 46.0, 0.0])
"""Middle of the full hand in its palm frame (wrist edge y = -48 mm, middle tip y = 142 mm)."""

R_PALM_DOWN = np.diag([-1.0, 1.0, -1.0])
"""World-from-palm rotation of a right hand lying palm-down with the fingers along world
+y: palm x -> world -x (the thumb on the user's left), y -> +y, z (palmar) -> world -z."""

@dataclass(frozen=True)
class Scenario:
    """A synthetic sequence: model, cameras and the true state of every frame.

    Attributes
    ----------
    name, description : what the scenario is called and shows.
    model : the tracking model (the nominal model file). The images may be rendered from a
        perturbed copy (``perturb_model``) while ``states`` stay the same numbers.
    rig : the cameras (world = tabletop, z up, mm).
    states : (T, n_q) ground-truth states, one per frame (read-only).
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


# --------------------------------------------------------------------------- helpers
def _set(model: KinematicModel, states: np.ndarray, name: str, values) -> None:
    states[:, model.state_index(name)] = values


def _place_hand(model: KinematicModel, states: np.ndarray, R_world_rest: np.ndarray,
                centre: np.ndarray, rotvecs: np.ndarray, offsets: np.ndarray) -> None:
    """Write the base states of a hand (quaternion + translation, in place): the rest
    orientation turned by the world rotation vectors ``rotvecs`` (T, 3) about the hand
    centre, which sits at ``centre + offsets`` (T, 3), world mm."""
    k = model.base_state
    quat = palm_quaternions(R_world_rest, rotvecs)
    states[:, k:k + 4] = quat
    states[:, k + 4:k + 7] = centre + offsets - matrix_from_quaternion(quat) @ HAND_CENTRE_PALM


def _finish(name: str, description: str, model: KinematicModel, rig: Rig,
            states: np.ndarray, fps: float, seed: int, n_frames: int | None,
            metadata: dict, per_frame: dict[str, np.ndarray] | None = None) -> Scenario:
    """Cut ``states`` and the ``per_frame`` arrays to ``n_frames`` (holding the last value
    past their end), clip to the joint limits, and add the per-frame image speed."""
    per_frame = dict(per_frame or {})
    if n_frames is not None:
        def fit(a: np.ndarray) -> np.ndarray:
            a = np.asarray(a)
            if n_frames > len(a):
                a = np.concatenate([a, np.repeat(a[-1:], n_frames - len(a), axis=0)])
            return a[:n_frames]

        states = fit(states)
        per_frame = {key: fit(value) for key, value in per_frame.items()}
    states = np.clip(states, model.lower, model.upper)
    states.setflags(write=False)  # the truth of a scenario does not change
    per_frame["image_speed_px"] = image_speed(model, states, rig)
    metadata = dict(metadata)
    for key, value in per_frame.items():
        metadata[key] = np.round(np.asarray(value, dtype=float), 4).tolist()
    return Scenario(name, description, model, rig, states, float(fps), int(seed), metadata)


# --------------------------------------------------------------------------- whole hand
WHOLE_HAND_CENTRE = np.array([0.0, 0.0, 110.0])
"""Where the palm-down hand of ``whole-hand`` and ``fast`` hovers: its centre 110 mm above
the table (world mm), so that flexed fingers stay clear of the table."""

WHOLE_HAND_TURN_LOW = np.array([-15.0, -8.0, -20.0])
WHOLE_HAND_TURN_HIGH = np.array([5.0, 8.0, 20.0])
"""Range of the palm rotation (degrees) about world x (pitch; positive lifts the
fingertips), y (roll, about the fingers) and z (yaw) in ``whole-hand``. Roll stays small
because it turns the hand edge-on to one camera, stacking the fingers and hiding the thumb
behind the palm; lifting the fingertips shows the thumb under the index finger."""

WHOLE_HAND_FLEX = 0.65
"""Largest common flexion (fraction of MCP 40, PIP 45, DIP 30 degrees) in ``whole-hand``;
each finger adds +-0.1 of its own. Beyond about 0.7 (80 degrees from MCP to DIP) a finger
seen from the cameras folds over itself and over its neighbours."""

THUMB_LOW = np.array([30.0, 0.0, -10.0, -5.0, -5.0])
THUMB_HIGH = np.array([45.0, 10.0, 10.0, 15.0, 15.0])
"""Range (degrees) of the thumb joints in ``whole-hand`` and ``fast``: spread from the
index finger, never crossing it."""


def _set_fingers(model: KinematicModel, q: np.ndarray, flex: np.ndarray,
                 abd: np.ndarray, thumb: np.ndarray) -> None:
    """Write finger and thumb angles into ``q`` (T, n_q), in place.

    ``flex`` (T, 4, 2): MCP and PIP flexion of index..little as fractions of 40 and 45
    degrees (clipped to [0, 1]); DIP is two thirds of PIP. ``abd`` (T, 4): abduction change
    (degrees) from the spread pose :data:`~digiteyes.kinematics.anatomy.SPREAD_DEG`.
    ``thumb`` (T, 5): degrees, order :data:`~digiteyes.kinematics.anatomy.THUMB_JOINTS`.
    """
    flex = np.clip(flex, 0.0, 1.0)
    for f, finger in enumerate(FINGERS):
        _set(model, q, f"{finger}.abd", (SPREAD_DEG[finger] + abd[:, f]) * DEG)
        _set(model, q, f"{finger}.mcp", 40.0 * DEG * flex[:, f, 0])
        _set(model, q, f"{finger}.pip", 45.0 * DEG * flex[:, f, 1])
        _set(model, q, f"{finger}.dip", 30.0 * DEG * flex[:, f, 1])
    for name, column in zip(THUMB_JOINTS, thumb.T, strict=True):
        _set(model, q, name, column * DEG)


def whole_hand(seed: int = 0, n_frames: int | None = None) -> Scenario:
    """Thesis Sec. 4.3.3: the full hand, palm-down above the table, seen by two cameras.

    Two cameras 450 mm apart, 550 mm from the hand, optical axes at 45 degrees to the table,
    in front of the fingertips (:func:`stereo_rig`). Palm: smooth translation (+-30 mm
    across, +-25 mm along, +-20 mm up) and rotation about the hand centre (yaw +-20, pitch
    -15..5, roll +-8 degrees, :data:`WHOLE_HAND_TURN_LOW`); fingers spread and flexing
    mostly in step, MCP up to 30, PIP up to 34 and DIP up to 22 degrees
    (:data:`WHOLE_HAND_FLEX`); abduction changes of +-4 degrees; the thumb moves in all five
    joints. Minimum-jerk moves between random keyframes every 3-5 s; 200 frames at 10 Hz
    (the thesis sequence lasted 20 s); at most about 6 px of image motion per frame. No
    link hides the axis of another, except where the proximal phalanges of the middle and
    ring fingers meet at their bases (the thesis tracked no features there).
    """
    rng = np.random.default_rng(seed)
    model = load_model("hand")
    n = max(200, n_frames or 0)

    def path(low, high):
        return random_keyframe_path(rng, n, low, high, 30, 50)

    common = path([0.0, 0.0], [WHOLE_HAND_FLEX, WHOLE_HAND_FLEX])
    own = np.stack([path([-0.1, -0.1], [0.1, 0.1]) for _ in FINGERS], axis=1)
    abd = np.stack([path([-4.0], [4.0])[:, 0] for _ in FINGERS], axis=1)
    thumb = path(THUMB_LOW, THUMB_HIGH)
    states = np.zeros((n, model.n_q))
    _set_fingers(model, states, common[:, None, :] + own, abd, thumb)
    offsets = path([-30, -25, -20], [30, 25, 20])
    rotvecs = path(WHOLE_HAND_TURN_LOW * DEG, WHOLE_HAND_TURN_HIGH * DEG)
    _place_hand(model, states, R_PALM_DOWN, WHOLE_HAND_CENTRE, rotvecs, offsets)
    meta = {"thesis": "Rehg thesis Sec. 4.3.3, Figs. 4.5-4.8",
            "hand_centre_world_mm": WHOLE_HAND_CENTRE.tolist()}
    return _finish("whole-hand", "Full 27-DOF hand: palm and fingers move without "
                   "occlusion, two cameras (thesis Sec. 4.3.3)", model,
                   stereo_rig(WHOLE_HAND_CENTRE), states, 10.0, seed, n_frames, meta)


# --------------------------------------------------------------------------- fast
def _periodic_hand(model: KinematicModel, phase: np.ndarray, lags: np.ndarray) -> np.ndarray:
    """States (T, n_q) of the periodic motion of ``fast`` at ``phase`` (T,) radians, inside
    the envelope of ``whole-hand`` (flexion, thumb, palm turn); ``lags`` (13,) random phase
    offsets. The palm circles, so that image speed is about uniform along the path."""
    p = np.asarray(phase, dtype=float)[:, None]
    finger_lag = 0.3 * np.arange(4)
    half = WHOLE_HAND_FLEX / 2
    mcp = half + half * np.sin(p + lags[0] + finger_lag)
    pip = half + half * np.sin(p + lags[0] + finger_lag - 0.8)
    abd = 3.0 * np.sin(0.5 * p + lags[1] + finger_lag)
    thumb = (THUMB_LOW + THUMB_HIGH) / 2 + (THUMB_HIGH - THUMB_LOW) / 2 * np.sin(
        0.8 * p + lags[2:7])
    q = np.zeros((len(p), model.n_q))
    _set_fingers(model, q, np.stack([mcp, pip], axis=2), abd, thumb)
    offsets = np.array([30.0, 25.0, 15.0]) * np.sin(np.array([1.0, 0.7, 0.5]) * p + lags[7:10])
    mid, amp = (WHOLE_HAND_TURN_HIGH + WHOLE_HAND_TURN_LOW) / 2, \
        (WHOLE_HAND_TURN_HIGH - WHOLE_HAND_TURN_LOW) / 2
    rotvecs = DEG * (mid + amp * np.sin(np.array([0.6, 0.4, 0.5]) * p + lags[10:13]))
    _place_hand(model, q, R_PALM_DOWN, WHOLE_HAND_CENTRE, rotvecs, offsets)
    return q


def fast(seed: int = 0, n_frames: int | None = None, start_px: float = 2.0,
         end_px: float = 36.0) -> Scenario:
    """The whole-hand motion, re-timed so that image speed grows linearly over the sequence.

    A periodic path (palm circling and turning, fingers flexing, all within the ranges of
    :func:`whole_hand`) is stepped frame by frame so that the largest keypoint displacement
    in either camera from frame t-1 to t is ``start_px + (end_px - start_px) t / (T - 1)``
    pixels, from well inside to well past a
    20 px search window: the frame where a tracker loses the hand measures its track life
    against speed (thesis Sec. 4.3.2). ``n_frames`` (default 200) stretches the ramp;
    ``metadata["image_speed_px"]`` holds the speeds reached. 10 Hz.
    """
    rng = np.random.default_rng(seed)
    model = load_model("hand")
    n = n_frames or 200
    rig = stereo_rig(WHOLE_HAND_CENTRE)
    lags = rng.uniform(0, 2 * np.pi, 13)
    targets = start_px + (end_px - start_px) * np.arange(n) / max(n - 1, 1)
    phases = np.zeros(n)
    step = 0.01
    for t in range(1, n):
        def excess(dp: float, t: int = t) -> float:
            pair = _periodic_hand(model, phases[t - 1] + np.array([0.0, dp]), lags)
            return image_speed(model, pair, rig)[1] - targets[t]

        low, high = 0.0, step
        while excess(high) < 0:
            low, high = high, 1.5 * high
        step = brentq(excess, low, high, xtol=1e-7, rtol=1e-4)
        phases[t] = phases[t - 1] + step
    meta = {"thesis": "Rehg thesis Sec. 4.3.2 (track loss when features leave the search "
                      "window), with the motion of Sec. 4.3.3",
            "hand_centre_world_mm": WHOLE_HAND_CENTRE.tolist()}
    return _finish("fast", f"Whole-hand motion, image speed growing linearly from "
                   f"{start_px:g} to {end_px:g} px/frame (track life against speed)", model,
                   rig, _periodic_hand(model, phases, lags), 10.0, seed, None, meta,
                   {"target_speed_px": targets, "phase_rad": phases})


# --------------------------------------------------------------------------- mouse
MOUSE_PHASES = ((0, 150, "index finger raised and lowered twice"),
                (150, 200, "index held up; thumb 'button' out and back"),
                (200, 350, "palm translation only, pole height constant"),
                (350, 500, "all states together"))
"""The four phases of the thesis's 500-frame 3D-mouse sequence (Sec. 4.3.4, Fig. 4.12)."""

MOUSE_TARGET = np.array([-30.0, 40.0, 15.0])
"""Where the 3D-mouse camera looks (world mm): between the resting hand and its thumb, so
that the whole palm travel stays in the image."""

MOUSE_RAISE = np.array([-28.0, 8.0, 4.0])
"""Index MCP, PIP, DIP (degrees) of a fully raised finger (the pole at its highest): the
MCP extends (negative lifts the tip off the table in mouse-hand.dh) while PIP and DIP
bend a little."""


def _mouse_motion(seed: int, n: int = 500) -> dict[str, np.ndarray]:
    """The channels of the 3D-mouse motion (thesis Fig. 4.12), (n,) each: palm ``x``,
    ``y`` (mm) and ``rot`` (deg) in the table plane, index ``lift`` (0 flat to 1 raised,
    :data:`MOUSE_RAISE`), ``little`` and ``thumb`` spread (deg). Phases as
    :data:`MOUSE_PHASES`; the last is random from ``seed``."""
    rng = np.random.default_rng(seed)
    t = np.arange(n)
    raise_keys = [(0, 0), (10, 0), (35, 1), (45, 1), (70, 0), (80, 0), (100, 0.8),
                  (108, 0.8), (128, 0), (134, 0), (150, 1), (350, 1)]
    thumb_keys = [(0, 0), (158, 0), (172, 25), (178, 25), (192, 0), (350, 0)]
    palm_keys = [(0, 0, 0, 0), (200, 0, 0, 0), (240, 60, 0, 0), (275, 60, 45, 0),
                 (315, -40, 35, 0), (350, 0, 0, 0)]
    little_keys = [(0, 0), (350, 0)]
    # Phase 4: random keyframes for (x, y, rot, raise, little, thumb).
    times = [350.0]
    while times[-1] < n - 1:
        times.append(times[-1] + rng.uniform(35, 50))
    low, high = np.array([-50, -40, -15, 0, 0, 0]), np.array([50, 40, 15, 1, 20, 25])
    randoms = rng.uniform(low, high, size=(len(times) - 1, 6))
    for time, (x, y, rot, lift, little, thumb) in zip(times[1:], randoms, strict=True):
        palm_keys.append((time, x, y, rot))
        raise_keys.append((time, lift))
        little_keys.append((time, little))
        thumb_keys.append((time, thumb))

    def keyed(keys):
        keys = np.array(keys, dtype=float)
        return keyframe_path(keys[:, 0], keys[:, 1:], t)

    palm = keyed(palm_keys)
    return {"x": palm[:, 0], "y": palm[:, 1], "rot": palm[:, 2],
            "lift": keyed(raise_keys)[:, 0], "little": keyed(little_keys)[:, 0],
            "thumb": keyed(thumb_keys)[:, 0]}


def mouse(seed: int = 0, n_frames: int | None = None) -> Scenario:
    """Thesis Sec. 4.3.4-4.3.5: the 3D-mouse hand on the table, one camera at 45 degrees.

    Phases (frames): 0-150 the index finger is raised and lowered twice (two peaks of the
    pole height, the second lower) and raised again by frame 150; 150-200 it stays up while
    the thumb abducts 25 degrees and returns (the "button event"); 200-350 the palm slides
    (moves of up to 100 mm, at most 47 mm/s, below the 2.5 in/s at which the thesis's
    tracker began to lose track) with everything else still; 350-500 palm position and
    rotation, index, little finger and thumb all move (random keyframes, the only part
    that depends on the seed). 10 Hz. ``metadata["index_tip_height_mm"]`` is the height of
    the index tip centre above the table per frame, the truth for the pole height.
    """
    model = load_model("mouse-hand")
    motion = _mouse_motion(seed)
    states = np.zeros((len(motion["x"]), model.n_q))
    _set(model, states, "palm.x", motion["x"])
    _set(model, states, "palm.y", motion["y"])
    _set(model, states, "palm.rot", motion["rot"] * DEG)
    for name, value in zip(("index.mcp", "index.pip", "index.dip"), MOUSE_RAISE, strict=True):
        _set(model, states, name, value * DEG * motion["lift"])
    _set(model, states, "little.abd", motion["little"] * DEG)
    _set(model, states, "thumb.abd", motion["thumb"] * DEG)
    rig = Rig((tabletop_camera("cam0", MOUSE_TARGET, 420.0, -65.0, 45.0),))
    kin = forward_kinematics(model, states)
    tip_row = model.link("index.tip").row
    height = kin.T_world_shape[:, tip_row, 2, 3]
    meta = {"thesis": "Rehg thesis Sec. 4.3.4-4.3.5, Figs. 4.10-4.13",
            "phases": [list(p) for p in MOUSE_PHASES]}
    return _finish("mouse", "3D-mouse hand on the table: index raise/lower, thumb button, "
                   "palm slide, all together (thesis Sec. 4.3.4)", model, rig, states, 10.0,
                   seed, n_frames, meta, {"index_tip_height_mm": height})


HAND_MOUSE_CENTRE = np.array([0.0, 0.0, 10.0])
"""Where the full hand's centre rests at the start of ``hand-mouse`` (world mm): the
finger axes 10 mm above the table, about a finger's radius."""


def hand_mouse(seed: int = 0, n_frames: int | None = None) -> Scenario:
    """The ``mouse`` scenario's motion played by the full hand (ours): the hand lies palm
    down on the table, fingers along +y, and a webcam looks down at it from the front
    left, 45 degrees above the table (as ``mouse``'s camera). The channels are those of
    ``mouse`` (:func:`_mouse_motion`, same phases and seed): the palm slides and turns
    about its centre, the index raises by :data:`MOUSE_RAISE`, the thumb spreads in the
    palm plane (``thumb.cmc_flex``) and the little finger abducts (``little.abd``), so the
    palm mapping of the 3D mouse (:class:`digiteyes.apps.palm_mouse.PalmMouse`) gives
    the same controls. For ``digiteyes mouse`` on footage, with truth. 10 Hz."""
    model = load_model("hand")
    motion = _mouse_motion(seed)
    n = len(motion["x"])
    states = np.zeros((n, model.n_q))
    rotvecs = np.zeros((n, 3))
    rotvecs[:, 2] = -motion["rot"] * DEG
    offsets = np.column_stack([motion["x"], motion["y"], np.zeros(n)])
    _place_hand(model, states, R_PALM_DOWN, HAND_MOUSE_CENTRE, rotvecs, offsets)
    for name, value in zip(("index.mcp", "index.pip", "index.dip"), MOUSE_RAISE, strict=True):
        _set(model, states, name, value * DEG * motion["lift"])
    _set(model, states, "little.abd", motion["little"] * DEG)
    _set(model, states, "thumb.cmc_flex", motion["thumb"] * DEG)
    rig = Rig((tabletop_camera("cam0", HAND_MOUSE_CENTRE + np.array([0.0, 20.0, 0.0]), 450.0,
                               -65.0, 45.0),))
    meta = {"phases": [list(p) for p in MOUSE_PHASES]}
    return _finish("hand-mouse", "the 3D-mouse motion by the full hand, palm down, seen by "
                   "a webcam 45 degrees above the table", model, rig, states, 10.0, seed,
                   n_frames, meta)


# --------------------------------------------------------------------------- two fingers
TWO_FINGER_CURL = np.array([65.0, 85.0, 55.0])
"""Index MCP, PIP, DIP (degrees) when curled into the palm."""

TWO_FINGER_TARGET = np.array([20.0, 45.0, 15.0])
"""Where the camera of ``two-finger-occlusion`` looks (world mm): the middle of the hand."""


def two_finger_occlusion(seed: int = 0, n_frames: int | None = None) -> Scenario:
    """Thesis Sec. 4.4.2: the index finger curls into the palm past the middle finger.

    The two-finger model (palm translation only, its palm frame parallel to the world)
    lies palm up, 12 mm above the table; one camera 500 mm away at 45 degrees to the table,
    beyond the fingertips and 40 degrees towards the index side, looks into the palm, so
    the curling index finger passes in front of the middle finger and the palm. The index
    curls in over frames 3-76 to MCP/PIP/DIP = 65/85/55 degrees (minimum-jerk); the middle
    finger flexes 6 degrees and back around frames 25-50 (the thesis saw such a small
    motion and recovered it); the palm does not move. 80 frames at 15 Hz; the index tip
    moves about 3 px per frame on average (``metadata["index_tip_speed_px"]``). The motion
    is fixed (``seed`` is kept for the record only).
    """
    model = load_model("two-finger")
    n = 80
    t = np.arange(n)
    curl = keyframe_path([0, 3, 76, 79], [0, 0, 1, 1], t)
    middle = keyframe_path([0, 25, 37, 50], [0, 0, 1, 0], t)
    states = np.zeros((n, model.n_q))
    _set(model, states, "palm.z", 12.0)
    for name, value in zip(("index.mcp", "index.pip", "index.dip"), TWO_FINGER_CURL,
                           strict=True):
        _set(model, states, name, value * DEG * curl)
    _set(model, states, "middle.mcp", 6.0 * DEG * middle)
    rig = Rig((tabletop_camera("cam0", TWO_FINGER_TARGET, 500.0, 40.0, 45.0),))
    kin = forward_kinematics(model, states)
    tip = kin.T_world_shape[:, model.link("index.tip").row, :3, 3]
    w = rig[0].project(tip)
    tip_speed = np.concatenate([[0.0], np.linalg.norm(np.diff(w, axis=0), axis=1)])
    meta = {"thesis": "Rehg thesis Sec. 4.4.2, Figs. 4.14-4.16"}
    return _finish("two-finger-occlusion", "Index finger curls into the palm past the "
                   "middle finger, one camera facing the palm (thesis Sec. 4.4.2)", model,
                   rig, states, 15.0, seed, n_frames, meta, {"index_tip_speed_px": tip_speed})


# --------------------------------------------------------------------------- natural
NATURAL_CENTRE = np.array([0.0, 0.0, 150.0])
_S = np.sqrt(0.5)
R_PALM_TO_CAMERAS = np.array([[-1.0, 0.0, 0.0], [0.0, -_S, _S], [0.0, _S, _S]])
"""World-from-palm rotation of a hand held up with the palm facing the cameras of
:func:`stereo_rig` (palmar normal along (0, 1, 1)/sqrt 2), fingers up and tilted back."""


def natural(seed: int = 0, n_frames: int | None = None) -> Scenario:
    """Huang, Wu & Lin Sec. 2: natural articulation as straight paths between basis poses.

    The hand starts open (``EEEEE``) and moves between randomly chosen basis
    configurations (:func:`basis_configurations`): each move follows the straight line
    between the two in joint space with minimum-jerk timing (1-1.7 s), then holds
    (0.2-0.7 s). The palm faces the two cameras and turns slowly (+-20 degrees about
    each world axis, keyframes every 2-3.3 s) and drifts +-15 mm. 200 frames at 30 Hz.
    ``metadata["basis_moves"]`` lists ``[start_frame, end_frame, from, to]``.
    """
    rng = np.random.default_rng(seed)
    model = load_model("hand")
    n = max(200, n_frames or 0)
    names = basis_configurations()
    key_times, key_names = [0.0], ["EEEEE"]
    moves = []
    while key_times[-1] < n - 1:
        start = key_times[-1] + rng.uniform(6, 21)
        end = start + rng.uniform(30, 50)
        choices = [b for b in names if b != key_names[-1]]
        target = choices[rng.integers(len(choices))]
        moves.append([int(np.ceil(start)), int(np.floor(end)), key_names[-1], target])
        key_times += [start, end]
        key_names += [key_names[-1], target]
    keys = np.array([basis_joint_angles(model, b) for b in key_names])
    states = keyframe_path(key_times, keys, np.arange(n))
    offsets = random_keyframe_path(rng, n, [-15] * 3, [15] * 3, 60, 100)
    rotvecs = random_keyframe_path(rng, n, [-20 * DEG] * 3, [20 * DEG] * 3, 60, 100)
    _place_hand(model, states, R_PALM_TO_CAMERAS, NATURAL_CENTRE, rotvecs, offsets)
    meta = {"thesis": "Huang, Wu & Lin Sec. 2 (basis configurations, linear manifolds)",
            "basis_configurations": {b: basis_joint_angles(model, b).tolist() for b in names},
            "basis_moves": [m for m in moves if m[0] < (n_frames or 200)],
            "hand_centre_world_mm": NATURAL_CENTRE.tolist()}
    return _finish("natural", "Natural articulation: straight joint-space paths between "
                   "28 basis poses, slow global rotation, two cameras (Huang et al. Sec. 2)",
                   model, stereo_rig(NATURAL_CENTRE), states, 30.0, seed, n_frames, meta)


# --------------------------------------------------------------------------- registry
SCENARIOS: dict[str, Callable[..., Scenario]] = {
    "whole-hand": whole_hand,
    "mouse": mouse,
    "two-finger-occlusion": two_finger_occlusion,
    "natural": natural,
    "fast": fast,
    "hand-mouse": hand_mouse,
}
"""Scenario builders by name; each is called as ``builder(seed=..., n_frames=...)``."""


def build_scenario(name: str, seed: int = 0, n_frames: int | None = None) -> Scenario:
    """Build a scenario by name (see :data:`SCENARIOS`), deterministically from ``seed``.

    ``n_frames`` overrides the scenario's length: scripted scenarios are cut (or hold their
    last state), random ones generate the longer motion (their first frames do not depend
    on ``n_frames``), and ``fast`` stretches its speed ramp over the new length. Raises
    :class:`DigitEyesError` for an unknown name or a bad frame count.
    """
    if name not in SCENARIOS:
        raise DigitEyesError(f"unknown scenario {name!r}; valid scenarios are "
                             f"{', '.join(SCENARIOS)}")
    if n_frames is not None and (int(n_frames) != n_frames or n_frames < 1):
        raise DigitEyesError(f"the number of frames must be a positive integer, got {n_frames}")
    if int(seed) != seed or seed < 0:
        raise DigitEyesError(f"the seed must be a non-negative integer, got {seed}")
    return SCENARIOS[name](seed=int(seed), n_frames=None if n_frames is None else int(n_frames))
