"""Perturbed copies of a model: the "true" hand that differs from the tracking model.

The thesis observes that tracking error shows up as "misalignments between anchor points
and knuckle positions" (Sec. 4.3.3): a real hand never matches its kinematic model. To
test trackers against that, :func:`perturb_model` draws a random model near the given one
by editing a copy of its :class:`~digiteyes.kinematics.model_file.ModelSpec`:

* link lengths: every ``cyl`` row's ``a`` is scaled by ``1 + u * link_length``;
* radii: every ``cyl`` radius is scaled by ``1 + u * radius``; a tip takes the factor of the
  link it ends (so the tip and the distal hemisphere stay matched); a palm box scales its
  smallest dimension (thickness) by a radius factor and the other two by length factors;
* anchors: the constant rows between a palm box and the first joint of each finger
  (thesis Table A.1 rows 1-2, 8-9, ...) get new ``d`` and ``a`` values that move the
  finger's first joint by a vector drawn uniformly from the ball of radius ``anchor_mm``
  (the least-norm change of those constants; if the rows cannot move the joint in some
  direction, that component is dropped).

Each ``u`` is uniform in [-1, 1], drawn per link in the order of ``model.links`` (then the
anchors, by row), so a seed gives the same model whatever the fractions.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from digiteyes.kinematics import KinematicModel, dh_transform
from digiteyes.kinematics.model_file import FrameSpec, ShapeSpec
from digiteyes.kinematics.scaling import scaled_model
from digiteyes.render.scene import tip_of_link
from digiteyes.synth.options import RenderError


def perturb_model(
    model: KinematicModel,
    *,
    link_length: float = 0.0,
    radius: float = 0.0,
    anchor_mm: float = 0.0,
    rng: np.random.Generator | int | None = None,
) -> KinematicModel:
    """A copy of ``model`` with randomly changed link lengths, radii and finger anchors.

    Parameters
    ----------
    model : the tracking model.
    link_length : largest relative change of a link length, in [0, 1).
    radius : largest relative change of a radius, in [0, 1).
    anchor_mm : largest displacement of a finger's first joint (mm), >= 0.
    rng : Generator or seed; the same seed gives the same model.

    Returns
    -------
    A new :class:`~digiteyes.kinematics.KinematicModel` with the same frames, states and
    limits. Raises :class:`~digiteyes.synth.options.RenderError` for bad fractions.
    """
    for name, value in (("link_length", link_length), ("radius", radius)):
        if not 0.0 <= value < 1.0:
            raise RenderError(f"perturb_model: {name} must be a fraction in [0, 1), got {value}")
    if not (math.isfinite(anchor_mm) and anchor_mm >= 0.0):
        raise RenderError(f"perturb_model: anchor_mm must be >= 0, got {anchor_mm}")
    rng = np.random.default_rng(rng)
    rows = {frame.index: frame for frame in model.spec.frames}
    tips = {tip: link for link, tip in tip_of_link(model).items()}
    radius_factor: dict[int, float] = {}
    for i, link in enumerate(model.links):
        if link.kind == "edge":
            continue  # tracked edges are features of the tracking model, never rendered
        u_length, u_radius = rng.uniform(-1.0, 1.0, size=2)
        f_length, f_radius = 1.0 + u_length * link_length, 1.0 + u_radius * radius
        row = rows[link.row]
        params = row.shape.params
        if link.kind == "link":
            radius_factor[i] = f_radius
            rows[link.row] = dataclasses.replace(
                row, a=row.a * f_length, shape=ShapeSpec("cyl", (params[0] * f_radius,)))
        elif link.kind == "tip":
            factor = radius_factor.get(tips.get(i, -1), f_radius)
            rows[link.row] = dataclasses.replace(row, shape=ShapeSpec("tip",
                                                                      (params[0] * factor,)))
        elif link.kind == "palm":
            size = np.array(params[:3])
            factors = np.full(3, f_length)
            factors[np.argmin(size)] = f_radius
            rows[link.row] = dataclasses.replace(
                row, shape=ShapeSpec("box", (*(size * factors), *params[3:])))
    for chain in anchor_chains(model):
        _shift_anchor(rows, chain, _ball_sample(rng, anchor_mm))
    frames = tuple(rows[frame.index] for frame in model.spec.frames)
    description = (f"{model.description} (perturbed: lengths +-{link_length:g}, radii "
                   f"+-{radius:g}, anchors {anchor_mm:g} mm)")
    return KinematicModel(dataclasses.replace(model.spec, frames=frames,
                                              description=description))


def anchor_chains(model: KinematicModel) -> list[tuple[int, ...]]:
    """Runs of constant rows (no state, no shape) leading from a palm box to a finger's
    first joint row, e.g. ``(1, 2)`` for the hand's index finger."""
    palms = [link.row for link in model.links if link.kind == "palm"]
    chains = []
    for palm in palms:
        for child in model.rows[palm].next:
            chain = []
            row = model.rows[child]
            while (row.theta_state is None and row.d_state is None and row.shape is None
                   and len(row.next) == 1):
                chain.append(row.index)
                row = model.rows[row.next[0]]
            if chain and (row.theta_state is not None or row.d_state is not None):
                chains.append(tuple(chain))
    return sorted(chains)


def _ball_sample(rng: np.random.Generator, radius: float) -> np.ndarray:
    """A point drawn uniformly from the ball of ``radius`` around the origin."""
    direction = rng.normal(size=3)
    direction /= np.linalg.norm(direction)
    return radius * rng.uniform() ** (1.0 / 3.0) * direction


def _shift_anchor(rows: dict[int, FrameSpec], chain: tuple[int, ...],
                  shift: np.ndarray) -> None:
    """Change ``d`` and ``a`` of the chain's rows so that the frame after the chain moves
    by ``shift`` (mm, in the frame of the chain's first row), least-norm."""
    columns = []
    R = np.eye(3)
    for index in chain:
        row = rows[index]
        columns.append(R[:, 2])  # d moves along the current z axis
        columns.append(R @ np.array([math.cos(row.theta), math.sin(row.theta), 0.0]))
        R = R @ dh_transform(row.theta, 0.0, 0.0, row.alpha)[:3, :3]
    A = np.stack(columns, axis=1)
    change = np.linalg.lstsq(A, shift, rcond=None)[0]
    for k, index in enumerate(chain):
        row = rows[index]
        rows[index] = dataclasses.replace(row, d=row.d + change[2 * k],
                                          a=row.a + change[2 * k + 1])


def scale_model(model: KinematicModel, factor: float) -> KinematicModel:
    """A copy of ``model`` scaled by ``factor`` about its root: every constant ``d`` and
    ``a``, radius, palm box size and centre times ``factor`` (a larger or smaller hand of
    the same proportions; hand sizes of adults span about 0.8 to 1.15 of Appendix A).
    Joint angles, states and limits are unchanged; prismatic states keep their values.
    Raises :class:`~digiteyes.synth.options.RenderError` for a factor outside (0.1, 10).
    """
    if not (isinstance(factor, (int, float)) and 0.1 < factor < 10.0):
        raise RenderError(f"scale_model: factor must be a number in (0.1, 10), got {factor!r}")
    return scaled_model(model, float(factor))
