"""The configuration space of finger articulation (Huang, Wu & Lin Sec. 2, eq. 1).

Finger joint-angle vectors (every ``angle`` state of a model, radians) are reduced by PCA to
a few dimensions (the paper keeps 7 of 20 with 95 % of the variance). In that space the 28
*basis configurations* (each digit fully extended or fully curled) and the straight
*manifolds* ``L_ij`` between them describe natural articulation (eq. 1).

A :class:`ConfigurationSpace` holds the PCA (mean, components, all variances), the basis
configurations in PCA coordinates and the joint limits; ``to_joints`` maps coordinates back
to joint angles, clipped to the limits. :func:`fit_configuration_space` learns one from
joint-angle samples; :func:`digiteyes.smc.prior.default_configuration_space` builds the
shipped default from the hand model alone.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from digiteyes.errors import DigitEyesError
from digiteyes.kinematics import KinematicModel


class PriorError(DigitEyesError, ValueError):
    """A configuration-space prior that cannot be built, read or used with a model."""


def finger_joint_indices(model: KinematicModel) -> np.ndarray:
    """State indices of the finger joints: every ``angle`` state (the palm pose excluded)."""
    idx = np.array([i for i, kind in enumerate(model.state_kinds) if kind == "angle"], dtype=int)
    if idx.size == 0:
        raise PriorError(f"model {model.name!r} has no joint angles to track")
    return idx


@dataclass(frozen=True)
class ConfigurationSpace:
    """PCA configuration space of finger joint angles (Huang eq. 1).

    Attributes
    ----------
    joint_names : (J,) names of the finger joint states, in model order.
    mean : (J,) mean joint-angle vector, rad.
    components : (D, J) orthonormal principal directions (rows), D kept dimensions.
    variances : (J,) every principal variance, descending, rad^2 (for reporting).
    basis_names : (M,) names of the basis configurations (``"ECCCE"``: thumb..little).
    basis : (M, D) basis configurations in PCA coordinates.
    lower, upper : (J,) joint limits, rad (``-inf``/``inf`` when unbounded).
    source : what the space was learnt from (free text, stored with it).
    """

    joint_names: tuple[str, ...]
    mean: np.ndarray
    components: np.ndarray
    variances: np.ndarray
    basis_names: tuple[str, ...]
    basis: np.ndarray
    lower: np.ndarray
    upper: np.ndarray
    source: str = ""

    @property
    def n_dims(self) -> int:
        """Kept dimensions D."""
        return int(self.components.shape[0])

    def kept_variance(self) -> np.ndarray:
        """Cumulative fraction of the variance kept by the first 1..J dimensions."""
        total = float(self.variances.sum())
        return np.cumsum(self.variances) / total if total > 0 else np.ones(len(self.variances))

    def to_coordinates(self, joints: np.ndarray) -> np.ndarray:
        """PCA coordinates (N, D) of joint-angle vectors (N, J) (or (J,) -> (D,))."""
        return (np.asarray(joints, dtype=float) - self.mean) @ self.components.T

    def to_joints(self, coordinates: np.ndarray) -> np.ndarray:
        """Joint angles (N, J) of PCA coordinates (N, D), clipped to the joint limits, rad."""
        joints = self.mean + np.asarray(coordinates, dtype=float) @ self.components
        return np.clip(joints, self.lower, self.upper)

    def joint_indices(self, model: KinematicModel) -> np.ndarray:
        """State indices in ``model`` of :attr:`joint_names`; raises :class:`PriorError`
        when the model lacks one of them."""
        missing = [n for n in self.joint_names if n not in model.state_names]
        if missing:
            raise PriorError(f"the prior ({self.source}) has joints {', '.join(missing)} that "
                             f"model {model.name!r} does not have")
        return np.array([model.state_index(n) for n in self.joint_names], dtype=int)

    def states(self, model: KinematicModel, base: np.ndarray, coordinates: np.ndarray
               ) -> np.ndarray:
        """Full states (N, n_q): ``base`` (n_q,) with its finger joints set from
        ``coordinates`` (N, D)."""
        coordinates = np.atleast_2d(coordinates)
        q = np.repeat(np.asarray(base, dtype=float)[None], len(coordinates), axis=0)
        q[:, self.joint_indices(model)] = self.to_joints(coordinates)
        return q

    def save(self, path: str | Path) -> Path:
        """Write the space to an ``.npz`` file; returns its path."""
        path = Path(path)
        np.savez(path, joint_names=np.array(self.joint_names), mean=self.mean,
                 components=self.components, variances=self.variances,
                 basis_names=np.array(self.basis_names), basis=self.basis, lower=self.lower,
                 upper=self.upper, source=np.array(self.source))
        return path

    @classmethod
    def load(cls, path: str | Path) -> ConfigurationSpace:
        """Read a space written by :meth:`save`; raises :class:`PriorError` naming the file."""
        path = Path(path)
        try:
            with np.load(path, allow_pickle=False) as data:
                fields = {k: data[k] for k in data.files}
        except (OSError, ValueError) as exc:
            raise PriorError(f"{path}: not a configuration-space .npz file ({exc})") from exc
        needed = ("joint_names", "mean", "components", "variances", "basis_names", "basis",
                  "lower", "upper")
        missing = [k for k in needed if k not in fields]
        if missing:
            raise PriorError(f"{path}: missing arrays {', '.join(missing)}")
        return cls(tuple(str(n) for n in fields["joint_names"]), fields["mean"],
                   fields["components"], fields["variances"],
                   tuple(str(n) for n in fields["basis_names"]), fields["basis"],
                   fields["lower"], fields["upper"], str(fields.get("source", "")))


def fit_configuration_space(samples: np.ndarray, joint_names: tuple[str, ...],
                            basis_joints: np.ndarray, basis_names: tuple[str, ...],
                            lower: np.ndarray, upper: np.ndarray, n_dims: int = 7,
                            source: str = "") -> ConfigurationSpace:
    """PCA of joint-angle samples (S, J), rad, keeping ``n_dims`` dimensions (Huang Sec. 2).

    ``basis_joints`` (M, J) are the basis configurations as joint angles; they are stored in
    the new PCA coordinates. Raises :class:`PriorError` for too few samples or a bad shape.
    """
    samples = np.asarray(samples, dtype=float)
    if samples.ndim != 2 or samples.shape[1] != len(joint_names):
        raise PriorError(f"joint-angle samples must be (S, {len(joint_names)}), got "
                         f"{samples.shape}")
    if len(samples) <= n_dims or not 1 <= n_dims <= len(joint_names):
        raise PriorError(f"need more than {n_dims} samples and 1 <= dims <= "
                         f"{len(joint_names)}; got {len(samples)} samples, {n_dims} dims")
    if not np.isfinite(samples).all():
        raise PriorError("joint-angle samples contain NaN or infinite values")
    mean = samples.mean(axis=0)
    _, sv, vt = np.linalg.svd(samples - mean, full_matrices=False)
    variances = np.zeros(len(joint_names))
    variances[:len(sv)] = sv ** 2 / (len(samples) - 1)
    components = vt[:n_dims]
    basis = (np.asarray(basis_joints, dtype=float) - mean) @ components.T
    return ConfigurationSpace(tuple(joint_names), mean, components, variances,
                              tuple(basis_names), basis, np.asarray(lower, dtype=float),
                              np.asarray(upper, dtype=float), source)
