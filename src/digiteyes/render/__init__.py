"""Drawing: posed primitives (scene), the numba ray caster (raster), pixel grids, lens
distortion. Any model, any camera; no knowledge of scenarios or ground truth (those live in
:mod:`digiteyes.synth`). See docs/rendering.md.
"""

from digiteyes.render.raster import Raster, paint, rasterise
from digiteyes.render.scene import Scene, build_scene

__all__ = ["Raster", "Scene", "build_scene", "paint", "rasterise"]
