"""Feature residuals and their analytic Jacobians (thesis eq. 2.17-2.20, report eq. 2-3, 6-10).

Link residual (thesis eq. 2.17, report eq. 3): for each valid measured line
``(a, b, rho)`` with unit normal ``m = (a, b)`` and each chosen point ``p`` on the link's
axis (by default its base and its end),

    l(q) = m . w(p(q)) - rho,             w = camera.project,

the signed pixel distance of the projected axis point from the measured line. Its
Jacobian row (thesis eq. 2.18, report eq. 6) is

    dl/dq = m^T (dw/dp) (dp/dq),

with ``dw/dp`` from :meth:`Camera.project_with_jacobian` (perspective with distortion,
orthographic or scaled orthographic) and ``dp/dq`` from
:func:`~digiteyes.kinematics.point_jacobian` (thesis eq. 2.16, report eq. 8-10).

Tip residual (report eq. 2): the 2-vector ``v(q) = w(c(q)) - t`` from the measured tip
``t`` to the projected tip centre ``c``, with Jacobian ``(dw/dp)(dp/dq)`` (report eq. 7).
We use the vector, not the norm ``|v|`` of thesis eq. 2.19: the norm's gradient
``v / |v|`` (eq. 2.20) is undefined at a perfect fit, where Gauss-Newton converges, while
the two components give the same cost ``|v|^2`` with a smooth Jacobian.

Rows are in pixels; columns are tangent steps (``form="tangent"``, ``model.n_v`` columns,
stepped with :func:`~digiteyes.kinematics.integrate`) or the raw state numbers
(``form="quaternion"``, ``model.n_q`` columns, thesis Sec. 2.2.1).
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import numpy as np

from digiteyes.camera import Camera
from digiteyes.errors import StateError
from digiteyes.features.measure import FeatureMeasurement
from digiteyes.kinematics import KinematicModel, Kinematics, point_jacobian


@dataclass(frozen=True)
class ResidualLayout:
    """Which residual rows belong to which feature (M rows).

    Attributes
    ----------
    camera : camera name of the measurement.
    kind : (M,) ``"link"`` or ``"tip"``.
    feature : (M,) position in ``meas.link_ids`` (links) or ``meas.tip_ids`` (tips).
    link_index : (M,) index into ``model.links``.
    component : (M,) link rows: number of the axis point (0 = base); tip rows: 0 = x, 1 = y.
    points_px : (M, 2) projection of the model point each row is evaluated at, px.
    """

    camera: str
    kind: np.ndarray
    feature: np.ndarray
    link_index: np.ndarray
    component: np.ndarray
    points_px: np.ndarray

    @property
    def n_rows(self) -> int:
        """Number of residual rows M."""
        return len(self.kind)

    def rows(self, kind: str) -> np.ndarray:
        """Row indices of one kind (``"link"`` or ``"tip"``)."""
        return np.flatnonzero(self.kind == kind)


@dataclass(frozen=True)
class _Rows:
    """Model points and row labels for a set of valid features (cached per selection)."""

    rows: np.ndarray  # shape-frame row of each model point
    p_shape: np.ndarray  # the points in their shape frames, mm
    n_link_rows: int
    kind: np.ndarray
    link_index: np.ndarray
    component: np.ndarray

    @staticmethod
    @lru_cache(maxsize=256)
    def build(model: KinematicModel, link_ids: tuple[int, ...], tip_ids: tuple[int, ...],
              axis_points: int) -> _Rows:
        fractions = np.linspace(0.0, 1.0, axis_points) if axis_points > 1 else np.zeros(1)
        lengths = np.array([model.links[i].length for i in link_ids], dtype=float)
        rows = np.concatenate([np.repeat([model.links[i].row for i in link_ids], axis_points),
                               [model.links[i].row for i in tip_ids]]).astype(int)
        n_link_rows = len(link_ids) * axis_points
        p_shape = np.zeros((len(rows), 3))
        p_shape[:n_link_rows, 0] = (lengths[:, None] * fractions[None, :]).ravel()
        arrays = dict(
            rows=rows, p_shape=p_shape,
            kind=np.array(["link"] * n_link_rows + ["tip"] * (2 * len(tip_ids)), dtype=str),
            link_index=np.concatenate([np.repeat(np.array(link_ids, dtype=int), axis_points),
                                       np.repeat(np.array(tip_ids, dtype=int), 2)]),
            component=np.concatenate([np.tile(np.arange(axis_points), len(link_ids)),
                                      np.tile([0, 1], len(tip_ids))]).astype(int),
        )
        for a in arrays.values():
            a.setflags(write=False)  # shared between calls through the cache
        return _Rows(n_link_rows=n_link_rows, **arrays)


def feature_residuals(
    meas: FeatureMeasurement,
    camera: Camera,
    kin: Kinematics,
    *,
    jacobian: bool = True,
    form: str = "tangent",
    axis_points: int = 2,
) -> tuple[np.ndarray, np.ndarray | None, ResidualLayout]:
    """Residuals of the valid features of one measurement at the state of ``kin``.

    Parameters
    ----------
    meas : measured lines and tips (held fixed).
    camera : the camera of ``meas``.
    kin : forward kinematics of ONE state.
    jacobian : also return the Jacobian.
    form : ``"tangent"`` (n_v columns) or ``"quaternion"`` (n_q columns).
    axis_points : points per link, evenly spaced from the link's base to its end (>= 1;
        1 uses the base only, as in thesis Sec. 4.3.1).

    Returns
    -------
    r : (M,) residuals, px: ``axis_points`` rows per valid link, then 2 rows per valid tip.
    J : (M, n) d r / d state, px per tangent unit (rad or mm), or None.
    layout : :class:`ResidualLayout`.
    """
    if form not in ("tangent", "quaternion"):
        raise ValueError(f"form must be 'tangent' or 'quaternion', got {form!r}")
    if axis_points < 1:
        raise ValueError(f"axis_points must be >= 1, got {axis_points}")
    if kin.T_world_shape.shape[0] != 1:
        raise StateError(
            f"feature_residuals needs the kinematics of one state, got "
            f"{kin.T_world_shape.shape[0]}"
        )
    links = np.flatnonzero(meas.link_valid)
    tips = np.flatnonzero(meas.tip_valid)
    rows_of = _Rows.build(kin.model, tuple(meas.link_ids[links]), tuple(meas.tip_ids[tips]),
                          axis_points)
    n_link_rows = rows_of.n_link_rows

    if jacobian:
        p_world, J_point = point_jacobian(kin, rows_of.rows, rows_of.p_shape, form=form)
        if J_point.ndim == 4:
            p_world, J_point = p_world[0], J_point[0]
    else:
        p_world = kin.points(rows_of.rows, rows_of.p_shape).reshape(-1, 3)
    w, dw = camera.project_with_jacobian(p_world, jacobian=jacobian)

    line = meas.line[links]
    m = np.repeat(line[:, :2], axis_points, axis=0)
    w_link, w_tip = w[:n_link_rows], w[n_link_rows:]
    r = np.concatenate([np.sum(m * w_link, axis=-1) - np.repeat(line[:, 2], axis_points),
                        (w_tip - meas.measured_tip[tips]).ravel()])
    J = None
    if jacobian:
        dw_dq = dw @ J_point  # (P, 2, n)
        J = np.concatenate([np.einsum("pi,pin->pn", m, dw_dq[:n_link_rows]),
                            dw_dq[n_link_rows:].reshape(-1, dw_dq.shape[-1])])
    layout = ResidualLayout(
        camera=meas.camera,
        kind=rows_of.kind,
        feature=np.concatenate([np.repeat(links, axis_points), np.repeat(tips, 2)]),
        link_index=rows_of.link_index,
        component=rows_of.component,
        points_px=np.concatenate([w_link, np.repeat(w_tip, 2, axis=0)]),
    )
    return r, J, layout
