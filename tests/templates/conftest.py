"""Fixtures of the template tests: the two-finger scenario's first frames, rendered once."""

from __future__ import annotations

import numpy as np
import pytest

from digiteyes.synth import RenderOptions, render_views
from digiteyes.synth.scenarios import build_scenario
from digiteyes.templates.filtering import LogFilter


@pytest.fixture(scope="session")
def two_finger():
    """(scenario, filtered images of frames 0 and 12) of ``two-finger-occlusion``."""
    scenario = build_scenario("two-finger-occlusion", n_frames=30)
    log = LogFilter(size=7)
    images = {i: log.apply(render_views(scenario.model, scenario.states[i], scenario.rig,
                                        RenderOptions(), rng=i)[0].image) for i in (0, 12)}
    return scenario, images


@pytest.fixture(scope="session")
def fd_gradient():
    """``fd_gradient(energy, n, h)``: central differences of ``energy(dv)`` along each of
    ``n`` step directions."""

    def gradient(energy, n: int, h: float = 1e-5) -> np.ndarray:
        out = np.zeros(n)
        for c in range(n):
            e = np.zeros(n)
            e[c] = h
            out[c] = (energy(e) - energy(-e)) / (2 * h)
        return out

    return gradient


@pytest.fixture(scope="session")
def setup(two_finger):
    """(scenario, images, model, camera, templates acquired on frame 0 at its state)."""
    from digiteyes.kinematics import forward_kinematics
    from digiteyes.occlusion.parts import template_parts
    from digiteyes.templates.layered import acquire_templates

    scenario, images = two_finger
    model, cam = scenario.model, scenario.rig[0]
    kin0 = forward_kinematics(model, scenario.states[0])
    templates = acquire_templates(template_parts(model), images[0], cam, kin0,
                                  spacing_px=2.0, margin=2.0)
    return scenario, images, model, cam, templates
