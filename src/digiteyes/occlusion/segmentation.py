"""List-priority segmentation (Rehg thesis Sec. 3.3.4): which part each pixel shows,
from the parts' image windows and the visibility order."""

from __future__ import annotations

import numpy as np

from digiteyes.occlusion._kernels import segment_kernel
from digiteyes.occlusion.visibility import VisibilityOrder
from digiteyes.occlusion.windows import ImageWindows


def segment_image(windows: ImageWindows, order: VisibilityOrder, width: int,
                  height: int) -> np.ndarray:
    """List-priority segmentation (thesis Sec. 3.3.4): (H, W) int16 part index of the
    front-most unit window at each pixel, -1 where none covers it."""
    labels = np.full((height, width), -1, dtype=np.int16)
    segment_kernel(order.order, windows.kind, windows.points, windows.radius,
                   windows.bounds(), labels)
    return labels
