"""Fixtures shared by several test folders: a one-link "stick" model (a cylinder of radius
8 mm and length 60 mm along its shape-frame x axis, ending in a tip sphere)."""

from __future__ import annotations

import pytest

from digiteyes.kinematics import KinematicModel, parse_model_text

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
