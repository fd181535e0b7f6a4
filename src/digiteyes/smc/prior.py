"""Configuration-space priors: the shipped default and one learnt from glove recordings.

The default (:func:`default_configuration_space`) contains no recorded data. It is the PCA
of joint-angle vectors generated deterministically (fixed seed) from the hand model alone:

* points on the manifolds between the 28 basis configurations (uniform ``s``), half the set;
* hands whose digits each curl independently by a random amount ``c`` in [0, 1]: every
  joint of the digit moves from its extended to its curled angle by ``c`` (so abduction
  shrinks as a finger curls: a curled finger lies beside its neighbours), except the DIP,
  held at 2/3 of the PIP (the coupling of Lin, Wu & Huang 2000), the other half of the set;
* 1 degree of Gaussian jitter on every joint, then clipping to the model's joint limits.

:func:`glove_joint_angles` maps CyberGlove recordings (23 DOF, West & Hogan's order) to a
model's finger states for ``digiteyes prior fit``, by the one glove mapping of the package
(:func:`digiteyes.synth.glove.glove_to_states`, the same that drives the ``glove``
scenarios); that data stays outside the package.
"""

from __future__ import annotations

from functools import lru_cache
from pathlib import Path

import numpy as np

from digiteyes.kinematics import KinematicModel
from digiteyes.kinematics.anatomy import digit_joint_angles
from digiteyes.smc.configuration import (
    ConfigurationSpace,
    PriorError,
    fit_configuration_space,
)
from digiteyes.smc.manifolds import (
    DEG,
    basis_joint_angles,
    basis_names,
    manifold_pairs,
    model_joint_names,
)
from digiteyes.synth.glove import glove_to_states

DEFAULT_PRIOR_SEED = 20011
"""Seed of the generated samples of the default prior (so it is the same everywhere)."""

GLOVE_COLUMNS = ("T_ROT", "T_MCP", "T_IP", "T_ABD", "I_MCP", "I_PIP", "I_DIP", "I_ABD",
                 "M_MCP", "M_PIP", "M_DIP", "M_ABD", "R_MCP", "R_PIP", "R_DIP", "R_ABD",
                 "L_MCP", "L_PIP", "L_DIP", "L_ABD", "PA", "W_PITCH", "W_YAW")
"""The 23 CyberGlove DOF in West & Hogan's order (radians; flexion negative)."""

def _generated_samples(joint_names: tuple[str, ...], rng: np.random.Generator,
                       n: int = 4000) -> np.ndarray:
    basis = basis_joint_angles(joint_names)
    pairs = manifold_pairs(len(basis))
    picks = pairs[rng.integers(len(pairs), size=n // 2)]
    s = rng.uniform(0.0, 1.0, size=(n // 2, 1))
    on_manifolds = s * basis[picks[:, 0]] + (1 - s) * basis[picks[:, 1]]

    column = {name: j for j, name in enumerate(joint_names)}
    digits = ("thumb", "index", "middle", "ring", "little")
    single = np.zeros((n - n // 2, len(joint_names)))
    curls = rng.uniform(0.0, 1.0, size=(len(single), len(digits)))
    for d, digit in enumerate(digits):
        open_, closed = digit_joint_angles(digit, True), digit_joint_angles(digit, False)
        c = curls[:, d]
        for name in open_:
            if name not in column:
                continue
            value = (1 - c) * open_[name] + c * closed[name]
            if name.endswith(".dip") and f"{digit}.pip" in closed:
                value = (2.0 / 3.0) * ((1 - c) * open_[f"{digit}.pip"] + c * closed[f"{digit}.pip"])
            single[:, column[name]] = value
    samples = np.concatenate([on_manifolds, single])
    return samples + rng.normal(0.0, 1.0 * DEG, size=samples.shape)


@lru_cache(maxsize=8)
def _default_for(joint_names: tuple[str, ...], lower: tuple[float, ...],
                 upper: tuple[float, ...], n_dims: int) -> ConfigurationSpace:
    rng = np.random.default_rng(DEFAULT_PRIOR_SEED)
    lo, hi = np.array(lower), np.array(upper)
    samples = np.clip(_generated_samples(joint_names, rng), lo, hi)
    return fit_configuration_space(samples, joint_names, basis_joint_angles(joint_names),
                                   basis_names(), lo, hi, n_dims,
                                   source="default: generated from the model's basis "
                                          "configurations and joint couplings")


def default_configuration_space(model: KinematicModel, n_dims: int = 7) -> ConfigurationSpace:
    """The shipped prior for ``model``: no recorded data, deterministic (see module doc)."""
    names = model_joint_names(model)
    idx = [model.state_index(n) for n in names]
    return _default_for(names, tuple(model.lower[idx]), tuple(model.upper[idx]), n_dims)


def read_glove_file(path: str | Path) -> list[np.ndarray]:
    """The recordings in a glove file: every (n, 23) joint-angle array, rad, rows with a
    non-finite value dropped.

    ``.mat`` (any variable holding (n, 23) arrays, cell arrays of them or (n, 23, k)
    stacks), ``.npy`` or ``.csv``/``.txt`` (23 numeric columns, ``#`` comments). Raises
    :class:`PriorError` naming the file when none is found.
    """
    path = Path(path)
    blocks: list[np.ndarray] = []

    def collect(a) -> None:
        a = np.asarray(a)
        if a.dtype == object:
            for item in a.flat:
                collect(item)
        elif a.ndim == 2 and a.shape[1] == len(GLOVE_COLUMNS) and a.dtype.kind == "f":
            blocks.append(a)
        elif a.ndim == 3 and a.shape[1] == len(GLOVE_COLUMNS) and a.dtype.kind == "f":
            blocks.extend(a[..., k] for k in range(a.shape[2]))

    try:
        if path.suffix.lower() == ".mat":
            from scipy.io import loadmat
            for key, value in loadmat(path).items():
                if not key.startswith("__"):
                    collect(value)
        elif path.suffix.lower() == ".npy":
            collect(np.load(path, allow_pickle=False))
        else:
            collect(np.loadtxt(path, delimiter=",", comments="#", ndmin=2))
    except (OSError, ValueError) as exc:
        raise PriorError(f"{path}: cannot read joint angles ({exc})") from exc
    recordings = [b[np.isfinite(b).all(axis=1)] for b in blocks]
    recordings = [r for r in recordings if len(r)]
    if not recordings:
        raise PriorError(f"{path}: no (n, {len(GLOVE_COLUMNS)}) joint-angle arrays found "
                         f"(expected CyberGlove columns {' '.join(GLOVE_COLUMNS)})")
    return recordings


def glove_joint_angles(model: KinematicModel, recording: np.ndarray,
                       joint_names: tuple[str, ...]) -> np.ndarray:
    """One glove recording (S, 23) as ``model``'s finger joints ``joint_names`` (S, J),
    rad, by :func:`digiteyes.synth.glove.glove_to_states` (abduction relative to its
    median over the recording, so pass whole recordings, not pieces)."""
    states = glove_to_states(model, recording)
    return states[:, [model.state_index(name) for name in joint_names]]


def fit_glove_prior(paths: list[str | Path], model: KinematicModel,
                    n_dims: int = 7) -> ConfigurationSpace:
    """Learn a configuration space from glove recordings for ``model`` (Huang Sec. 2)."""
    if not paths:
        raise PriorError("give at least one joint-angle recording")
    names = model_joint_names(model)
    idx = [model.state_index(n) for n in names]
    lo, hi = model.lower[idx], model.upper[idx]
    recordings = [r for p in paths for r in read_glove_file(p)]
    samples = np.clip(np.concatenate([glove_joint_angles(model, r, names)
                                      for r in recordings]), lo, hi)
    return fit_configuration_space(samples, names, basis_joint_angles(names), basis_names(),
                                   lo, hi, n_dims,
                                   source=f"glove: {len(samples)} samples from "
                                          f"{len(paths)} file(s)")
