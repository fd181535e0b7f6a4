"""The user's link widths, measured on the first frame (a calibration of the model).

One camera sees a link's distance through its apparent width (the width residual of
:mod:`digiteyes.features.residuals`), and that cue is only as good as the model's radii.
A hand whose fingers are thinner than the model's (the flesh hand of docs/appearance.md
is tapered; so are most real fingers) looks farther away than it is: from the true start
of the webcam setup, the first frame's solve moved the flesh hand 21 mm deeper and its
fingertips 17-45 mm off (docs/features.md, "Width calibration").

Huang, Wu & Lin calibrate their patch sizes to the user from a frame of the open palm
(Sec. 4.2), and Rehg leaves fitting the model to the user as future work (Ch. 6). Here a
link's radius factor is the ratio of its measured to its predicted width at a state
known to be right (the start of a track):

    scale_k = measured_k / (predicted_k - bias_k),   predicted_k(s) = s predicted_k(1),

the widths taken at the middle slice of the link (px). ``bias_k`` is the predicted edge
bias of the shading model (:mod:`digiteyes.features.appearance`): shading pulls both
edges inwards by a fixed fraction of the width, so a link ``scale_k`` times as wide loses
``scale_k bias_k``. Only links that lie where the state says are measured, so a start a
centimetre or more off (an automatic one) gives no factors. The feature tracker then
measures at its solved states, on the first frame that fits: a factor measured there can
absorb a depth error the solve leaves, but on the automatic starts of ``bench
auto-start`` the user's widths on the first frame did more good than that harm
(docs/initialisation.md, "The widths measured after the first solve").

A perspective cylinder's apparent width is ``2 f r / sqrt(z^2 - r^2)``: for a finger of
10 mm radius at 300 mm the slope between radius factors 1 and :data:`PROBE` is within
0.2 % of the width at 1, so two evaluations of the width rows give the predicted width
without reaching into the kernels. Factors are
clipped to :data:`LIMITS`; links not measured get the median of the others; factors
within :data:`DEAD_BAND` of 1 are 1.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from digiteyes.camera import Camera
from digiteyes.features.appearance import EdgeBias
from digiteyes.features.measure import FeatureMeasurement
from digiteyes.features.residuals import feature_residuals
from digiteyes.kinematics import Kinematics

PROBE = 1.25
"""Radius factor of the second evaluation (any factor other than 1 gives the same)."""
LIMITS = (0.6, 1.4)
"""Smallest and largest radius factor: beyond them a width belongs to something else (a
neighbouring finger's edge, a shadow)."""
MAX_AXIS_PX = 1.5
"""A link whose measured axis lies farther than this (px) from the predicted one at either
axis point is not where the state puts it: its width is not used."""
DEAD_BAND = 0.05
"""Factors within this of 1 are set to 1: the measurement's own spread (the model's own
links measure 0.997-1.003 on its rendered whole-hand frame, and up to 1.03 where the drawn
links are 5 % longer or shorter than the model's). A long one-camera track is chaotic: a
0.1 % change of the radii turned the 3-iteration `whole-hand` track of our own drawing
from 8.0 to 18.4 mm, and one factor of 1.03 its perturbed-hand track from 9.6 to 14.1 mm,
so a correction within the precision would only add chance."""
MIN_LINKS = 5
"""Fewest links measured for the factors to be given (else None: the state does not fit
the image)."""
MAX_SPREAD = 0.1
"""Largest difference of one link's factors in two cameras."""
MAX_DIFFERENCE = 0.6
"""Width rows whose measured width is off the predicted one by more than this fraction
are not used (the tracker's own bound, ``max_width_error``, assumes the model's radii)."""


def link_radius_scales(measurements: Sequence[FeatureMeasurement], cameras: Sequence[Camera],
                       kin: Kinematics, edge_bias: Sequence[EdgeBias] = (),
                       axis_points: int = 2, width_weight: float = 1.0
                       ) -> np.ndarray | None:
    """Radius factor (len(model.links),) of every link from one frame's measurements
    (one per camera, made at the state of ``kin``), or None when fewer than
    :data:`MIN_LINKS` links could be measured (the state does not fit the image).

    A link is measured in a camera that found both of its sides, where its measured axis
    lies within :data:`MAX_AXIS_PX` of the predicted one (the state puts the link where it
    is: an automatic start that is centimetres off measures nothing). Its factor is the
    mean over those cameras, kept only if they agree within :data:`MAX_SPREAD` (else a
    side line was a neighbour's). Links without a width (tips, the palm) get 1; links not
    measured, the median factor of the measured ones. ``edge_bias`` (per camera,
    optional) is the tracker's predicted bias, made with its ``width_weight``."""
    model = kin.model
    n_links = len(model.links)
    probe = np.full(n_links, PROBE)
    ratios: list[list[float]] = [[] for _ in range(n_links)]
    options = dict(jacobian=False, axis_points=axis_points, width_weight=1.0,
                   max_width_error=MAX_DIFFERENCE)
    for index, (meas, camera) in enumerate(zip(measurements, cameras, strict=True)):
        r1, _, layout1 = feature_residuals(meas, camera, kin, **options)
        r2, _, layout2 = feature_residuals(meas, camera, kin, radius_scale=probe, **options)
        bias = np.zeros(len(r1))
        if index < len(edge_bias) and width_weight > 0:
            bias = np.array(edge_bias[index].of_rows(layout1.kind_code, layout1.link_index,
                                                     layout1.component), dtype=float)
            bias[layout1.rows("width")] /= width_weight  # the tracker's rows carry the weight
        axis = layout1.rows("link")
        misplaced = {int(link) for link, value in zip(layout1.link_index[axis],
                                                      r1[axis] - bias[axis], strict=True)
                     if abs(value) > MAX_AXIS_PX}
        probed = {int(layout2.link_index[row]): r2[row] for row in layout2.rows("width")}
        for row in layout1.rows("width"):
            link = int(layout1.link_index[row])
            if link not in probed or link in misplaced:
                continue
            predicted = (probed[link] - r1[row]) / (PROBE - 1.0)  # px, at factor 1
            if predicted > bias[row] > -predicted:
                ratios[link].append((predicted - r1[row]) / (predicted - bias[row]))
    factor = {link: float(np.mean(r)) for link, r in enumerate(ratios)
              if r and max(r) - min(r) <= MAX_SPREAD}
    if len(factor) < MIN_LINKS:
        return None
    fallback = float(np.median(list(factor.values())))
    scales = np.ones(n_links)
    for link_index, link in enumerate(model.links):
        if link.kind == "link":
            value = float(np.clip(factor.get(link_index, fallback), *LIMITS))
            scales[link_index] = 1.0 if abs(value - 1.0) < DEAD_BAND else value
    return scales
