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
