"""Kinks of phi (Abs, Min, Max): the normal-cone centre at a kink (eq. 86)."""

import numpy as np
import pytest
import sympy as sp
from scenes import simulator

import vcigen


@pytest.mark.parametrize("backend", ["casadi", "c"])
@pytest.mark.parametrize("rule", ["trapezoid", "midpoint"])
def test_star_dropped_flat_bounces_straight_up(rule, backend):
    """theta = 0 is a kink of eq. (81): two vertices touch at once; no side may be picked."""
    res = simulator("star", rule, backend).simulate(q0=[0.0, 1.0, 0.0], v0=[0.5, 0.0, 0.0], h=0.01, t_end=0.5)
    assert res.n_impacts == 1
    assert np.max(np.abs(res.q[:, 2])) < 1e-15 and np.max(np.abs(res.p[:, 2])) < 1e-15
    assert res.impacts[0].energy_after == pytest.approx(res.impacts[0].energy_before, abs=1e-12)
    assert res.p[-1, 1] > 0


def test_min_contact_box_corner_symmetric():
    """A particle into the corner of phi = Min(x, y) at 45 degrees comes straight back."""
    x, y, xd, yd = sp.symbols("x y xd yd")
    model = vcigen.Model(
        name="corner",
        q=[x, y],
        qdot=[xd, yd],
        lagrangian=(xd**2 + yd**2) / 2,
        contacts={"corner": sp.Min(x, y)},
    )
    res = vcigen.build(model).simulate(q0=[0.5, 0.5], v0=[-1.0, -1.0], h=0.025, t_end=1.0)
    assert res.n_impacts == 1
    np.testing.assert_allclose(res.p[-1], [1.0, 1.0], atol=1e-12)
    np.testing.assert_allclose(res.q[-1], [0.5, 0.5], atol=1e-12)
