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
from digiteyes.features._residual_kernels import RESIDUAL_KINDS, feature_residuals_kernel
from digiteyes.features.measure import FeatureMeasurement
from digiteyes.features.slices import view_of
from digiteyes.kinematics import KinematicModel, Kinematics
from digiteyes.kinematics.jacobian import jacobian_tables
from digiteyes.kinematics.step_form import StepForm

_KIND_NAMES = np.array(RESIDUAL_KINDS)


@dataclass(frozen=True)
class ResidualLayout:
    """Which residual rows belong to which feature (M rows).

    Attributes
    ----------
    camera : camera name of the measurement.
    kind_code : (M,) position of each row's kind in ``RESIDUAL_KINDS``
        (``"link"``, ``"tip"``, ``"width"``).
    feature : (M,) position in ``meas.link_ids`` (links, widths) or ``meas.tip_ids`` (tips).
    link_index : (M,) index into ``model.links``.
    component : (M,) link rows: number of the axis point (0 = base); tip rows: 0 = x, 1 = y;
        width rows: 0.
    points_px : (M, 2) projection of the model point each row is evaluated at, px.
    """

    camera: str
    kind_code: np.ndarray
    feature: np.ndarray
    link_index: np.ndarray
    component: np.ndarray
    points_px: np.ndarray

    @property
    def kind(self) -> np.ndarray:
        """(M,) kind of each row: ``"link"``, ``"tip"`` or ``"width"``."""
        return _KIND_NAMES[self.kind_code]

    @property
    def n_rows(self) -> int:
        """Number of residual rows M."""
        return len(self.kind_code)

    def rows(self, kind: str) -> np.ndarray:
        """Row indices of one kind (``"link"``, ``"tip"`` or ``"width"``)."""
        if kind not in RESIDUAL_KINDS:
            raise ValueError(f"kind must be one of {', '.join(RESIDUAL_KINDS)}, got {kind!r}")
        return np.flatnonzero(self.kind_code == RESIDUAL_KINDS.index(kind))


def feature_residuals(
    meas: FeatureMeasurement,
    camera: Camera,
    kin: Kinematics,
    *,
    jacobian: bool = True,
    form: StepForm | str = StepForm.TANGENT,
    axis_points: int = 2,
    width_weight: float = 0.0,
    max_width_error: float = 0.15,
    radius_scale: np.ndarray | None = None,
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
    radius_scale : (len(model.links),) factor on each link's radius in the predicted
        widths (the user's fingers measured on the first frame,
        :mod:`digiteyes.features.width_scale`); None: the model's radii.

    Returns
    -------
    r : (M,) residuals, px: ``axis_points`` rows per valid link, 2 rows per valid tip, then
        one row per measured width.
    J : (M, n) d r / d state, px per tangent unit (rad or mm), or None.
    layout : :class:`ResidualLayout`.
    """
    form = StepForm.parse(form)
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
    model = kin.model
    table = _link_table(model)
    if radius_scale is not None:
        scale = np.asarray(radius_scale, dtype=float)
        if scale.shape != (len(model.links),) or not np.all(scale > 0):
            raise ValueError(f"radius_scale must hold {len(model.links)} positive factors, "
                             f"got shape {scale.shape}")
        table = (*table[:3], table[3] * scale)
    n_links, n_tips = len(meas.link_ids), len(meas.tip_ids)
    n_max = axis_points * n_links + 2 * n_tips + n_links
    n_cols = form.n_columns(model) if jacobian else 0
    r, J = np.empty(n_max), np.empty((n_max, n_cols))
    points_px = np.empty((n_max, 2))
    labels = np.empty((4, n_max), dtype=np.int64)  # kind code, feature, link index, component
    middle = meas.slice_centres.shape[1] // 2
    view, perspective = view_of(camera)
    n = feature_residuals_kernel(
        kin.T_world_shape, kin.q, jacobian_tables(model, form),
        (camera.projection_params, view, perspective),
        (meas.link_ids, meas.link_valid, meas.line, meas.side_lines, meas.slice_normal,
         meas.slice_centres[:, middle] if middle else np.zeros((n_links, 2)),
         float(meas.slice_fractions[middle]) if middle else 0.5,
         meas.tip_ids, meas.tip_valid, meas.measured_tip),
        table, axis_points, float(width_weight),
        float(max_width_error), jacobian, r, J, points_px, *labels)
    kind_code, feature, link_index, component = labels[:, :n]
    layout = ResidualLayout(camera=meas.camera, kind_code=kind_code, feature=feature,
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
