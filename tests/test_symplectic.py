"""The one-step map (q_k, p_k) -> (q_k+1, p_k+1) is symplectic, impact steps included (sec. 3.3)."""

import numpy as np
import pytest
from scenes import simulator

from vcigen.analysis import symplectic_defect
from vcigen.stepper import Stepper

RULES = ["trapezoid", "midpoint"]


def step_map(sim, h, count):
    kern = sim.kernels.bind(sim.model.resolve_params(None))
    stepper = Stepper(kern, sim.tol)

    def f(z):
        n = z.size // 2
        impacts = []
        q, p, _, _ = stepper.step(0, 0.0, h, z[:n], z[n:], z[n:], impacts)
        count.append(len(impacts))
        return np.concatenate([q, p])

    return f


@pytest.mark.parametrize("rule", RULES)
def test_impact_step_is_symplectic(rule):
    sim = simulator("billiard", rule)
    h = 0.05
    count = []
    f = step_map(sim, h, count)
    # A state 0.6 h before the rim along the velocity: the step holds one impact at alpha ~ 0.6.
    q = np.array([0.0, 1.0 - 0.6 * h * 1.5 - 1e-3])
    z = np.concatenate([q, [0.4, 1.5]])
    defect = symplectic_defect(f, z, eps=1e-6)
    assert set(count) == {1}, "every perturbed step must hold exactly one impact"
    assert defect < 1e-7, defect


@pytest.mark.parametrize("rule", RULES)
def test_star_impact_step_is_symplectic(rule):
    sim = simulator("star_nonlinear", rule)
    h = 0.01
    count = []
    f = step_map(sim, h, count)
    # phi(q) = 0.64 - 0.625 = 0.015 and the star falls 0.03 in the step: a vertex strikes.
    z = np.array([0.0, 0.64, 0.3, -1.0, -3.0, 2.0])
    defect = symplectic_defect(f, z, eps=1e-6)
    assert set(count) == {1}
    assert defect < 1e-7, defect


def test_defect_detects_a_non_symplectic_map():
    """The measure is not vacuous: a dissipative map has a large defect."""
    assert symplectic_defect(lambda z: np.concatenate([z[:2], 0.9 * z[2:]]), np.ones(4)) > 0.05
