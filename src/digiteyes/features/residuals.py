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

Width residual (our addition, docs/features.md "Width residual"): the axis residuals say
nothing about how far a finger is from a single camera, which is why flexion towards it
goes unseen (thesis Sec. 2.5.4). The apparent width of a link does: it shrinks as ``f r / z``.
For each link whose two side lines were measured, ``width_weight`` times

    d(q) = n . (w(t1(q)) - w(t0(q))) - [ (m0 - m1) . c(q) - (rho0 - rho1) ],

the predicted minus the measured width, px: ``t0, t1`` are the contour points of the
cross-section through the link's middle (where viewing rays graze the cylinder), ``n`` the
unit slice normal, ``c = (w(t0) + w(t1)) / 2`` and ``(m_k, rho_k)`` the two side lines. The
contour points sit where the silhouette width is extremal, so their motion around the
cylinder does not change it to first order: holding them fixed on the link gives the exact
Jacobian. Rows whose ``|d|`` exceeds ``max_width_error`` times the predicted width are
left out (a side line on a neighbouring finger, not this one).

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
from digiteyes.features._kernels import contour_points_kernel, residual_rows_kernel
from digiteyes.features.measure import FeatureMeasurement
from digiteyes.features.slices import view_of
from digiteyes.kinematics import KinematicModel, Kinematics, point_jacobian


@dataclass(frozen=True)
class ResidualLayout:
    """Which residual rows belong to which feature (M rows).

    Attributes
    ----------
    camera : camera name of the measurement.
    kind : (M,) ``"link"``, ``"tip"`` or ``"width"``.
    feature : (M,) position in ``meas.link_ids`` (links, widths) or ``meas.tip_ids`` (tips).
    link_index : (M,) index into ``model.links``.
    component : (M,) link rows: number of the axis point (0 = base); tip rows: 0 = x, 1 = y;
        width rows: 0.
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
        """Row indices of one kind (``"link"``, ``"tip"`` or ``"width"``)."""
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
    width_weight: float = 0.0,
    max_width_error: float = 0.15,
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
    width_weight : weight of the width residuals (module docstring); 0 leaves them out, as
        in the thesis.
    max_width_error : width rows whose predicted and measured widths differ by more than
        this fraction of the predicted width are left out.

    Returns
    -------
    r : (M,) residuals, px: ``axis_points`` rows per valid link, 2 rows per valid tip, then
        one row per measured width.
    J : (M, n) d r / d state, px per tangent unit (rad or mm), or None.
    layout : :class:`ResidualLayout`.
    """
    if form not in ("tangent", "quaternion"):
        raise ValueError(f"form must be 'tangent' or 'quaternion', got {form!r}")
    if axis_points < 1:
        raise ValueError(f"axis_points must be >= 1, got {axis_points}")
    if not (width_weight >= 0 and max_width_error > 0):
        raise ValueError(f"width_weight must be >= 0 and max_width_error > 0, got "
                         f"{width_weight!r} and {max_width_error!r}")
    if kin.T_world_shape.shape[0] != 1:
        raise StateError(
            f"feature_residuals needs the kinematics of one state, got "
            f"{kin.T_world_shape.shape[0]}"
        )
    links = np.flatnonzero(meas.link_valid)
    tips = np.flatnonzero(meas.tip_valid)
    rows_of = _Rows.build(kin.model, tuple(meas.link_ids[links]), tuple(meas.tip_ids[tips]),
                          axis_points)
    n_link_rows, n_rows = rows_of.n_link_rows, len(rows_of.rows)
    widths = _width_links(meas, kin.model) if width_weight > 0 else np.zeros(0, dtype=int)
    rows, p_shape = rows_of.rows, rows_of.p_shape
    if len(widths):
        w_rows, w_shape = _contour_points(meas, camera, kin, widths)
        rows, p_shape = np.concatenate([rows, w_rows]), np.concatenate([p_shape, w_shape])

    if jacobian:
        p_world, J_point = point_jacobian(kin, rows, p_shape, form=form)
        if J_point.ndim == 4:
            p_world, J_point = p_world[0], J_point[0]
    else:
        p_world = kin.points(rows, p_shape).reshape(-1, 3)
        J_point = np.zeros((len(rows), 3, 0))
    w, dw = camera.project_with_jacobian(p_world, jacobian=jacobian)
    if dw is None:
        dw = np.zeros((len(rows), 2, 3))
    n_max = n_rows + len(tips) + len(widths)
    r = np.empty(n_max)
    J = np.empty((n_max, J_point.shape[-1]))
    points_px = np.empty((n_max, 2))
    keep = np.empty(len(widths), dtype=bool)
    middle = meas.slice_centres[widths, meas.slice_centres.shape[1] // 2] if len(widths) \
        else np.zeros((0, 2))
    n = residual_rows_kernel(w, dw, J_point, jacobian, axis_points, n_link_rows,
                             meas.line[links], meas.measured_tip[tips],
                             meas.slice_normal[widths], meas.side_lines[widths], middle,
                             float(width_weight), float(max_width_error), r, J, points_px, keep)
    kind, link_index, component = rows_of.kind, rows_of.link_index, rows_of.component
    feature = np.concatenate([np.repeat(links, axis_points), np.repeat(tips, 2)])
    if len(widths):
        widths = widths[keep]
        kind = np.concatenate([kind, np.full(len(widths), "width")])
        feature = np.concatenate([feature, widths])
        link_index = np.concatenate([link_index, meas.link_ids[widths]])
        component = np.concatenate([component, np.zeros(len(widths), dtype=int)])
    layout = ResidualLayout(camera=meas.camera, kind=kind, feature=feature,
                            link_index=link_index, component=component, points_px=points_px[:n])
    return r[:n], J[:n] if jacobian else None, layout


@lru_cache(maxsize=64)
def _link_table(model: KinematicModel) -> tuple[np.ndarray, ...]:
    """Per link of ``model``: whether it is a cylinder (has a width; not a body edge), its
    shape-frame row, length and radius (mm)."""
    links = model.links
    table = (np.array([link.kind == "link" for link in links], dtype=bool),
             np.array([link.row for link in links], dtype=np.int64),
             np.array([link.length for link in links], dtype=float),
             np.array([link.radius for link in links], dtype=float))
    for a in table:
        a.setflags(write=False)  # shared between calls through the cache
    return table


def _width_links(meas: FeatureMeasurement, model: KinematicModel) -> np.ndarray:
    """Positions in ``meas.link_ids`` of valid cylinder links with both side lines."""
    both = np.isfinite(meas.side_lines).all(axis=(1, 2))
    return np.flatnonzero(meas.link_valid & both & _link_table(model)[0][meas.link_ids])


def _contour_points(meas: FeatureMeasurement, camera: Camera, kin: Kinematics,
                    widths: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Shape-frame rows and coordinates (2K, 3) of the two contour points of the middle
    slice's cross-section of each link in ``widths`` (positions in ``meas.link_ids``), mm."""
    _, rows, lengths, radii = _link_table(kin.model)
    ids = meas.link_ids[widths]
    middle = meas.slice_fractions[len(meas.slice_fractions) // 2]
    view, perspective = view_of(camera)
    local = np.empty((len(ids), 2, 3))
    contour_points_kernel(kin.T_world_shape[0], rows[ids], middle * lengths[ids], radii[ids],
                          view, perspective, camera.projection_params,
                          meas.slice_normal[widths], local)
    return np.repeat(rows[ids], 2), local.reshape(-1, 3)
