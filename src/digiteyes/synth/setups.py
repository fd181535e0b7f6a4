"""Camera setups that users and the seeds have, as scenarios.

Three places for the cameras, each with one or two cameras (docs/scenarios.md):

``desk``        the thesis's desk camera (Sec. 4.3.3, 4.4.2): about 45 degrees above the
                table, behind and beside a palm-down right hand; the fingers curl towards
                the table in turn and pass out of sight under the palm. Two cameras: a
                second one on the other side of the wrist, 450 mm away (1.5 ft, as in the
                thesis).
``webcam``      a camera in front of the user, 10 degrees above the hand, looking at a
                palm held up and facing it; the fingers curl towards the camera in turn.
                Two cameras: a stereo pair 120 mm apart.
``egocentric``  a camera at the eyes looking down (55 degrees) at a palm-down hand
                reaching forward on the table; two cameras: a head-mounted pair 65 mm apart.

The motion (:func:`curl_in_turn`) is the same in all three: each finger in turn curls
deeply (MCP up to 75, PIP up to 100, DIP up to 65 degrees) and opens again while its
neighbours flex a little, the thumb moves in all five joints, and the palm drifts and
turns slowly. World frame and conventions as in :mod:`digiteyes.synth.scenarios`.

Hand size: ``hand_scale`` (0.8 to 1.15 of Appendix A for adults) is kept in
``metadata["hand_scale"]``; :func:`truth_model` gives the scaled model the images should
be drawn from, while the scenario's ``model`` (the tracking model) stays at 1.0.
"""

from __future__ import annotations

import numpy as np

from digiteyes.camera import Rig
from digiteyes.errors import DigitEyesError
from digiteyes.kinematics import KinematicModel, load_model
from digiteyes.synth.motion import keyframe_path, random_keyframe_path
from digiteyes.synth.perturb import scale_model
from digiteyes.synth.scenarios import (
    DEG,
    FINGERS,
    R_PALM_DOWN,
    THUMB_HIGH,
    THUMB_LOW,
    Scenario,
    _finish,
    _place_hand,
    _set,
    tabletop_camera,
)

SETUPS = ("desk", "webcam", "egocentric")
HAND_SCALES = (0.8, 1.15)
"""Range of adult hand sizes relative to Appendix A accepted by the setups."""

R_PALM_TO_FRONT = np.array([[-1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, 1.0, 0.0]])
"""World-from-palm rotation of a hand held up (fingers along world +z) with its palm
facing a camera on the world +y side (palmar normal along world +y)."""

CURL_DEG = np.array([75.0, 100.0, 65.0])
"""MCP, PIP, DIP (degrees) of a fully curled finger in :func:`curl_in_turn`."""

_PLACES = {
    # setup: (rest rotation, hand centre (world mm), camera distance, elevation (deg),
    #         azimuth of one camera (deg), azimuth offsets of two cameras, turn limits (deg))
    "desk": (R_PALM_DOWN, np.array([0.0, 0.0, 60.0]), 500.0, 45.0, 150.0, (150.0, 210.0),
             np.array([8.0, 8.0, 15.0])),
    "webcam": (R_PALM_TO_FRONT, np.array([0.0, 0.0, 200.0]), 450.0, 10.0, 0.0,
               (-7.6, 7.6), np.array([15.0, 15.0, 15.0])),
    "egocentric": (R_PALM_DOWN, np.array([0.0, 0.0, 60.0]), 450.0, 55.0, 180.0,
                   (175.8, 184.2), np.array([8.0, 8.0, 20.0])),
}


def setup_rig(setup: str, n_cameras: int = 1) -> Rig:
    """The cameras of a setup (one or two, 640 x 480, 800 px focal length)."""
    _, centre, distance, elevation, azimuth, pair, _ = _place(setup)
    if n_cameras not in (1, 2):
        raise DigitEyesError(f"a setup has 1 or 2 cameras, got {n_cameras}")
    azimuths = (azimuth,) if n_cameras == 1 else pair
    return Rig(tuple(tabletop_camera(f"cam{i}", centre, distance, az, elevation)
                     for i, az in enumerate(azimuths)))


def _place(setup: str):
    if setup not in _PLACES:
        raise DigitEyesError(f"unknown camera setup {setup!r}; valid setups are "
                             f"{', '.join(SETUPS)}")
    return _PLACES[setup]


def curl_in_turn(model: KinematicModel, n: int, rng: np.random.Generator,
                 period: int = 40) -> np.ndarray:
    """Joint states (n, n_q) with a zero base: the fingers curl in turn.

    Finger f (index, middle, ring, little, then again) curls over frames
    ``[f period, (f + 1) period)`` to a random 60-100 % of :data:`CURL_DEG` and opens
    again (minimum-jerk); meanwhile the others flex up to 15 % of it (random keyframes);
    abduction varies +-5 degrees about a slight spread; the thumb moves within
    ``THUMB_LOW..THUMB_HIGH`` of ``whole-hand``.
    """
    t = np.arange(n)
    q = np.zeros((n, model.n_q))
    spread = {"index": -8.0, "middle": 0.0, "ring": 6.0, "little": 14.0}
    for f, finger in enumerate(FINGERS):
        rest = random_keyframe_path(rng, n, [0.0], [0.15], 25, 45)[:, 0]
        keys_t, keys_v = [-1.0], [0.0]
        for start in range(f * period, n, 4 * period):
            depth = rng.uniform(0.6, 1.0)
            keys_t += [start, start + 0.45 * period, start + 0.55 * period, start + period]
            keys_v += [0.0, depth, depth, 0.0]
        curl = keyframe_path(np.array(keys_t), np.array(keys_v)[:, None], t)[:, 0]
        amount = np.maximum(curl, rest)
        abd = spread[finger] + random_keyframe_path(rng, n, [-5.0], [5.0], 30, 50)[:, 0]
        _set(model, q, f"{finger}.abd", abd * DEG)
        for joint, full in zip(("mcp", "pip", "dip"), CURL_DEG, strict=True):
            _set(model, q, f"{finger}.{joint}", full * DEG * amount)
    thumb = random_keyframe_path(rng, n, THUMB_LOW, THUMB_HIGH, 30, 50)
    for name, column in zip(("thumb.cmc_flex", "thumb.cmc_abd", "thumb.mp_abd", "thumb.mp",
                             "thumb.ip"), thumb.T, strict=True):
        _set(model, q, name, column * DEG)
    return q


def setup_scenario(setup: str, n_cameras: int = 1, hand_scale: float = 1.0, seed: int = 0,
                   n_frames: int | None = None, joints: np.ndarray | None = None,
                   fps: float = 10.0, name: str | None = None,
                   source: str = "curl_in_turn") -> Scenario:
    """A scenario of camera ``setup`` with ``n_cameras`` cameras.

    ``joints`` (T, n_q) gives the joint states (base ignored) of another motion (e.g.
    :mod:`digiteyes.synth.glove`); without it the fingers curl in turn
    (:func:`curl_in_turn`, 160 frames). The palm drifts +-20 mm and turns within the
    setup's limits about the hand centre. ``hand_scale`` in [0.8, 1.15] is recorded for
    :func:`truth_model`.
    """
    rest, centre, *_, turn = _place(setup)
    if not HAND_SCALES[0] <= hand_scale <= HAND_SCALES[1]:
        raise DigitEyesError(f"hand_scale must be in [{HAND_SCALES[0]}, {HAND_SCALES[1]}], "
                             f"got {hand_scale}")
    rng = np.random.default_rng(seed)
    model = load_model("hand")
    rig = setup_rig(setup, n_cameras)
    if joints is None:
        n = max(160, n_frames or 0)
        states = curl_in_turn(model, n, rng)
    else:
        states = np.array(joints, dtype=float)
        n = len(states)
    offsets = random_keyframe_path(rng, n, [-20.0] * 3, [20.0] * 3, 40, 60)
    rotvecs = random_keyframe_path(rng, n, -turn * DEG, turn * DEG, 40, 60)
    _place_hand(model, states, rest, centre, rotvecs, offsets)
    label = name or f"{setup}-{n_cameras}cam"
    meta = {"setup": setup, "cameras": n_cameras, "hand_scale": float(hand_scale),
            "motion": source, "hand_centre_world_mm": centre.tolist(),
            "thesis": "Rehg thesis Sec. 4.3.3 (desk cameras at 45 degrees)"
            if setup == "desk" else "user camera setup"}
    return _finish(label, f"{setup} camera setup, {n_cameras} camera(s), {source}", model,
                   rig, states, fps, seed, n_frames, meta)


def truth_model(scenario: Scenario) -> KinematicModel:
    """The model to draw a scenario's images from: its tracking model scaled by
    ``metadata["hand_scale"]`` (1.0 when absent)."""
    scale = float(scenario.metadata.get("hand_scale", 1.0))
    return scenario.model if scale == 1.0 else scale_model(scenario.model, scale)


def _builder(setup: str, n_cameras: int):
    def build(seed: int = 0, n_frames: int | None = None) -> Scenario:
        return setup_scenario(setup, n_cameras, seed=seed, n_frames=n_frames)

    build.__doc__ = f"The {setup} camera setup with {n_cameras} camera(s), fingers curling " \
                    "in turn (:func:`setup_scenario`)."
    return build


def glove_scenario(setup: str, n_cameras: int = 1, subject: int = 0, trial: int = 0,
                   task: str = "R2G", hand_scale: float = 1.0, seed: int = 0,
                   n_frames: int | None = None, fps: float = 30.0,
                   path: str | None = None) -> Scenario:
    """A camera setup driven by a real CyberGlove recording (:mod:`digiteyes.synth.glove`)
    resampled to ``fps``; the palm drifts and turns as in :func:`setup_scenario`. Raises
    :class:`DigitEyesError` when the glove data are not found."""
    from digiteyes.synth.glove import glove_to_states, load_glove, resample

    times, angles = load_glove(subject, trial, task, path)
    joints = glove_to_states(load_model("hand"), resample(times, angles, fps))
    return setup_scenario(setup, n_cameras, hand_scale, seed, n_frames, joints, fps,
                          name=f"glove-{setup}-{n_cameras}cam",
                          source=f"CyberGlove {task} subject {subject} trial {trial}")


def _builder(setup: str, n_cameras: int, glove: bool = False):
    def build(seed: int = 0, n_frames: int | None = None) -> Scenario:
        if glove:  # the seed picks the recording: subject seed % 7, trial (seed // 7) % 5
            return glove_scenario(setup, n_cameras, subject=seed % 7, trial=(seed // 7) % 5,
                                  seed=seed, n_frames=n_frames)
        return setup_scenario(setup, n_cameras, seed=seed, n_frames=n_frames)

    build.__doc__ = (f"The {setup} camera setup with {n_cameras} camera(s), "
                     + ("CyberGlove motion (:func:`glove_scenario`)." if glove else
                        "fingers curling in turn (:func:`setup_scenario`)."))
    return build


SETUP_SCENARIOS = {f"{prefix}{setup}-{n}cam": _builder(setup, n, glove=bool(prefix))
                   for prefix in ("", "glove-") for setup in SETUPS for n in (1, 2)}
"""``desk-1cam``, ``desk-2cam``, ``webcam-1cam``, ..., ``glove-desk-1cam``, ... :
builders with the scenario registry's signature ``(seed, n_frames)``; the ``glove-``
family needs the CyberGlove data (:func:`digiteyes.synth.glove.glove_dir`)."""
