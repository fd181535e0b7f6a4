"""How well a predicted visibility order agrees with a renderer's depth buffer.

At every pixel that two or more unit windows cover, the predicted segmentation
(:func:`~digiteyes.occlusion.segmentation.segment_image`, front-most window in the predicted
order) names a part; the renderer's label image names the surface it drew there (from
its depth buffer). The agreement is the share of those contested pixels where both name
the same part, counted only where the renderer saw one of the covering parts (a window
is a model outline, so it also covers a little background and other parts' rims).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from digiteyes.camera import Camera
from digiteyes.kinematics import Kinematics
from digiteyes.occlusion._kernels import segment_kernel
from digiteyes.occlusion.parts import TemplatePart, facing_plane
from digiteyes.occlusion.visibility import VisibilityOrder, predict_visibility
from digiteyes.occlusion.windows import image_windows


@dataclass(frozen=True)
class OrderAgreement:
    """Counts at the contested pixels of one view: ``agree`` of ``contested``."""

    agree: int
    contested: int

    @property
    def fraction(self) -> float:
        """Share of agreeing pixels (1.0 when nothing was contested)."""
        return self.agree / self.contested if self.contested else 1.0


def order_agreement(parts: tuple[TemplatePart, ...], kin: Kinematics, camera: Camera,
                    rendered_labels: np.ndarray,
                    order: VisibilityOrder | None = None) -> OrderAgreement:
    """Compare the visibility order predicted at the state of ``kin`` (or ``order``) with
    ``rendered_labels`` (H, W), the renderer's index into ``model.links`` per pixel."""
    planes = [facing_plane(p, kin, camera) for p in parts]
    windows = image_windows(parts, planes, kin, camera)
    order = predict_visibility(parts, windows, camera) if order is None else order
    h, w = rendered_labels.shape
    bounds = windows.bounds()
    predicted = np.full((h, w), -1, dtype=np.int16)
    segment_kernel(order.order, windows.kind, windows.points, windows.radius, bounds,
                   predicted)
    link_to_part = np.full(int(max(p.link for p in parts)) + 2, -1)
    for k, p in enumerate(parts):
        link_to_part[p.link] = k
    seen = np.where(rendered_labels >= 0, link_to_part[np.maximum(rendered_labels, 0)], -1)
    cover = np.zeros((h, w), dtype=np.int16)
    covered_by_seen = np.zeros((h, w), dtype=bool)
    for k in range(len(parts)):
        single = np.full((h, w), -1, dtype=np.int16)
        segment_kernel(np.array([k]), windows.kind, windows.points, windows.radius, bounds,
                       single)
        cover += single >= 0
        covered_by_seen |= (single >= 0) & (seen == k)
    contested = (cover >= 2) & covered_by_seen
    return OrderAgreement(int((predicted[contested] == seen[contested]).sum()),
                          int(contested.sum()))
