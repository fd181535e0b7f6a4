"""Real human finger motion from CyberGlove recordings, mapped to the hand model's states.

The data (West & Hogan, "Kinematic hand synergies differ between reach-and-grasp and
functional object manipulation"; 7 subjects, 23 joint angles in radians at about 33 Hz)
are read at run time from a folder the user gives, ``$DIGITEYES_GLOVE_DIR``, or
``../shared/data/glove`` (from the working directory or the repository); nothing derived
from them ships with the package. Files used: ``SourceData/X_<task>_SUBJECTbyOBJECT_raw.mat``
(a 7 x 5 cell array of n x 23 angle arrays) and ``t_<task>_SUBJECTbyOBJECT_raw.mat`` (times,
s), ``task`` ``R2G`` (reach and grasp of five objects) or ``Manipulation`` (five steps).

Glove columns (SourceData/README.md): 0-3 thumb rotation, MCP, IP, abduction; then for
index, middle, ring and little finger MCP, PIP, DIP, abduction (4-19); 20-22 palm arch,
wrist pitch and yaw. In the recordings flexion is negative (closing a fist drives MCP and
PIP towards -1.5 rad). The mapping to ``hand`` (docs/models.md signs) is:

* finger ``mcp``, ``pip``, ``dip`` = minus the glove angle (flexion positive), clipped to
  the model's limits;
* finger ``abd`` = rest spread (index -8, middle 0, ring 6, little 14 degrees) plus the
  change of the glove's abduction from its median over the recording, with the sign
  that spreads the finger away from the middle finger (index -1, ring and little +1);
  the middle finger keeps its rest value (the glove measures spreads between fingers);
* thumb: ``thumb.mp`` = glove T MCP and ``thumb.ip`` = glove T IP (flexion is negative in
  both); ``thumb.cmc_flex`` = 35 degrees + T ABD (away from the index finger);
  ``thumb.cmc_abd`` = 20 degrees - (T Rot - its median) (rotation into the palm lifts the
  thumb to the palmar side); ``thumb.mp_abd`` = 0;
* palm arch, wrist pitch and yaw are not used: the palm's pose comes from the camera
  setup's own drift (:func:`digiteyes.synth.setups.setup_scenario`).

This is an approximate, documented correspondence (the glove's sensor placement and
calibration differ from the model's joint axes), good for realistic timing and
coordination of the fingers, not for anatomical accuracy.
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from digiteyes.errors import DigitEyesError
from digiteyes.kinematics import KinematicModel

DEG = np.pi / 180.0
TASKS = ("R2G", "Manipulation")
N_SUBJECTS, N_OBJECTS = 7, 5
REST_SPREAD_DEG = {"index": -8.0, "middle": 0.0, "ring": 6.0, "little": 14.0}
SPREAD_SIGN = {"index": -1.0, "middle": 0.0, "ring": 1.0, "little": 1.0}
FINGER_COLUMNS = {"index": 4, "middle": 8, "ring": 12, "little": 16}


def glove_dir(path: str | os.PathLike | None = None) -> Path:
    """The folder of the glove data: ``path``, else ``$DIGITEYES_GLOVE_DIR``, else
    ``../shared/data/glove`` from the working directory or the repository. Raises
    :class:`DigitEyesError` naming the places tried when none holds ``SourceData``."""
    candidates = [Path(path)] if path is not None else []
    if path is None and os.environ.get("DIGITEYES_GLOVE_DIR"):
        candidates.append(Path(os.environ["DIGITEYES_GLOVE_DIR"]))
    if path is None:
        candidates += [Path.cwd() / ".." / "shared" / "data" / "glove",
                       Path(__file__).resolve().parents[3] / ".." / "shared" / "data" / "glove"]
    for folder in candidates:
        if (folder / "SourceData").is_dir():
            return folder
    raise DigitEyesError("CyberGlove data not found (looked for a SourceData folder in "
                         f"{', '.join(str(c) for c in candidates)}); pass the folder of the "
                         "glove data or set DIGITEYES_GLOVE_DIR")


def load_glove(subject: int, trial: int, task: str = "R2G",
               path: str | os.PathLike | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Times (n,) s from the start, strictly increasing (of samples with the same time
    stamp the first is kept), and raw glove angles (n, 23) rad of one recording:
    ``subject`` 0-6, ``trial`` 0-4 (object or step), ``task`` ``R2G`` or ``Manipulation``."""
    if task not in TASKS:
        raise DigitEyesError(f"glove task must be one of {', '.join(TASKS)}, got {task!r}")
    if not (0 <= subject < N_SUBJECTS and 0 <= trial < N_OBJECTS):
        raise DigitEyesError(f"glove subject must be 0-{N_SUBJECTS - 1} and trial "
                             f"0-{N_OBJECTS - 1}, got {subject}, {trial}")
    from scipy.io import loadmat

    folder = glove_dir(path) / "SourceData"
    angles = _cell(loadmat(folder / f"X_{task}_SUBJECTbyOBJECT_raw.mat"), subject, trial)
    times = _cell(loadmat(folder / f"t_{task}_SUBJECTbyOBJECT_raw.mat"), subject, trial)
    angles = np.asarray(angles, dtype=float)
    times = np.asarray(times, dtype=float).ravel()
    if angles.ndim != 2 or angles.shape[1] != 23 or len(times) != len(angles):
        raise DigitEyesError(f"{folder}: recording ({subject}, {trial}) has angles of shape "
                             f"{angles.shape} and {len(times)} times; expected n x 23 and n")
    times, first = np.unique(times, return_index=True)  # a few stamps repeat
    return times - times[0], angles[first]


def _cell(mat: dict, subject: int, trial: int) -> np.ndarray:
    keys = [k for k in mat if not k.startswith("__")]
    if len(keys) != 1:
        raise DigitEyesError(f"expected one variable in the glove file, got {keys}")
    return mat[keys[0]][subject, trial]


def glove_to_states(model: KinematicModel, angles: np.ndarray) -> np.ndarray:
    """Joint states (n, n_q) of ``model`` (``hand``; base zero) from glove angles (n, 23),
    by the mapping of the module docstring, clipped to the joint limits."""
    a = np.asarray(angles, dtype=float)
    q = np.zeros((len(a), model.n_q))

    def put(name: str, values: np.ndarray) -> None:
        q[:, model.state_index(name)] = values

    for finger, col in FINGER_COLUMNS.items():
        for k, joint in enumerate(("mcp", "pip", "dip")):
            put(f"{finger}.{joint}", -a[:, col + k])
        spread = a[:, col + 3] - np.median(a[:, col + 3])
        put(f"{finger}.abd", REST_SPREAD_DEG[finger] * DEG + SPREAD_SIGN[finger] * spread)
    put("thumb.mp", a[:, 1])
    put("thumb.ip", a[:, 2])
    put("thumb.cmc_flex", 35.0 * DEG + a[:, 3])
    put("thumb.cmc_abd", 20.0 * DEG - (a[:, 0] - np.median(a[:, 0])))
    joints = slice(model.base_state + 7, None) if model.base_state is not None else slice(None)
    q[:, joints] = np.clip(q[:, joints], model.lower[joints], model.upper[joints])
    return q


def resample(times: np.ndarray, values: np.ndarray, fps: float) -> np.ndarray:
    """``values`` (n, m) sampled at ``times`` (n,) s, linearly interpolated at ``fps``."""
    grid = np.arange(0.0, times[-1] + 1e-9, 1.0 / fps)
    return np.stack([np.interp(grid, times, column) for column in values.T], axis=1)
