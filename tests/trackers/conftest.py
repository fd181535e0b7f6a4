"""Fixtures shared by the tracker tests."""

from __future__ import annotations

import numpy as np
import pytest

from digiteyes.camera import Rig
from digiteyes.synth import RenderOptions, render_views
from digiteyes.synth.scenarios import build_scenario


@pytest.fixture(scope="session")
def desk():
    """The desk view, one camera, the independent flesh hand with sensor noise: (model,
    rig, state with the index straight, the same with it curled, image of each)."""
    scenario = build_scenario("desk-1cam", seed=0, n_frames=2)
    model, rig = scenario.model, Rig(scenario.rig.cameras[:1])
    q = np.array(scenario.states[0])
    curled = q.copy()
    for joint, angle in (("mcp", 80.0), ("pip", 95.0), ("dip", 60.0)):
        curled[model.state_index(f"index.{joint}")] = np.radians(angle)
    options = RenderOptions(appearance="flesh", noise_sigma=2.0)
    image = render_views(model, q, rig, options, rng=0)[0].image
    image_curled = render_views(model, curled, rig, options, rng=1)[0].image
    return model, rig, q, curled, image, image_curled
