"""Fixtures shared by several test folders: a one-link "stick" model (a cylinder of radius
8 mm and length 60 mm along its shape-frame x axis, ending in a tip sphere), and the desk
view of the flesh hand with its index finger straight and curled, over black cloth in grey
and over clutter in colour."""

from __future__ import annotations

import numpy as np
import pytest

from digiteyes.camera import Rig
from digiteyes.kinematics import KinematicModel, parse_model_text
from digiteyes.synth import RenderOptions, render_views
from digiteyes.synth.scenarios import build_scenario

STICK = """
model stick
description one cylinder link (radius 8 mm, 60 mm long) ending in a tip sphere
[states]
q0  base.qw  quat
q1  base.qx  quat
q2  base.qy  quat
q3  base.qz  quat
q4  base.x   trans
q5  base.y   trans
q6  base.z   trans
q7  joint    angle
[frames]
0   -           pose:q0  0  0   0  -       1
1   stick.link  q7       0  60  0  cyl(8)  2
2   stick.tip   0        0  0   0  tip(8)  -
"""


@pytest.fixture(scope="session")
def stick() -> KinematicModel:
    return KinematicModel(parse_model_text(STICK))


def _desk_states():
    """The desk view, one camera: (model, rig, state with the index straight, the same
    with it curled)."""
    scenario = build_scenario("desk-1cam", seed=0, n_frames=2)
    model, rig = scenario.model, Rig(scenario.rig.cameras[:1])
    q = np.array(scenario.states[0])
    curled = q.copy()
    for joint, angle in (("mcp", 80.0), ("pip", 95.0), ("dip", 60.0)):
        curled[model.state_index(f"index.{joint}")] = np.radians(angle)
    return model, rig, q, curled


@pytest.fixture(scope="session")
def desk():
    """The desk view, one camera, the independent flesh hand with sensor noise: (model,
    rig, state with the index straight, the same with it curled, image of each)."""
    model, rig, q, curled = _desk_states()
    options = RenderOptions(appearance="flesh", noise_sigma=2.0)
    image = render_views(model, q, rig, options, rng=0)[0].image
    image_curled = render_views(model, curled, rig, options, rng=1)[0].image
    return model, rig, q, curled, image, image_curled


@pytest.fixture(scope="session")
def desk_noisy_colour():
    """:func:`desk` in colour over a plain dark backdrop with sensor noise of 14 grey
    levels per channel (about 10 in grey): (model, rig, state, image)."""
    model, rig, q, _ = _desk_states()
    options = RenderOptions(appearance="flesh", noise_sigma=14.0, color=True,
                            background="uniform", background_level=0.3)
    return model, rig, q, render_views(model, q, rig, options, rng=0)[0].image


@pytest.fixture(scope="session")
def desk_clutter():
    """:func:`desk` in colour over clutter: (model, rig, state, image, image of the curled
    index)."""
    model, rig, q, curled = _desk_states()
    options = RenderOptions(appearance="flesh", noise_sigma=2.0, color=True,
                            background="clutter", background_seed=3)
    images = [render_views(model, s, rig, options, rng=i)[0].image
              for i, s in enumerate((q, curled))]
    return model, rig, q, *images
