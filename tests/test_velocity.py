"""``res.v``: the continuous Legendre transform inverted at each grid point (issue 13), both backends.

Checked against closed forms written here, not against vcigen: the double pendulum's mass matrix
(p = M(q) v), and a relativistic particle (L = -m sqrt(1 - v^2), p = m v / sqrt(1 - v^2), so
v = p / sqrt(m^2 + p^2)), whose Legendre transform is not linear in v.
"""

from __future__ import annotations

import numpy as np
import pytest
import sympy as sp
from hard_scenes import backend_param, simulator

import vcigen


def pendulum_mass(q: np.ndarray) -> np.ndarray:
    """m1 = m2 = l1 = l2 = 1: [[2, cos(t1 - t2)], [cos(t1 - t2), 1]]."""
    c = np.cos(q[:, 0] - q[:, 1])
    return np.stack([np.stack([2 + 0 * c, c], -1), np.stack([c, 1 + 0 * c], -1)], -2)


@pytest.mark.parametrize("backend", [backend_param("c"), backend_param("casadi")])
def test_v_inverts_the_double_pendulum_legendre_transform(backend: str) -> None:
    q0, v0 = [0.3, 0.6], [1.5, 2.0]
    res = simulator("double_pendulum", backend).simulate(q0, v0, 0.01, t_end=0.5)
    assert res.n_impacts >= 1
    exact = np.linalg.solve(pendulum_mass(res.q), res.p[..., None])[..., 0]
    assert res.v.shape == res.q.shape
    np.testing.assert_allclose(res.v, exact, rtol=1e-13, atol=1e-13)
    np.testing.assert_allclose(res.v[0], v0, rtol=1e-14)  # p_0 = dL/dqdot(q0, v0)


def test_v_of_a_lagrangian_not_quadratic_in_the_velocity() -> None:
    x, xd = sp.symbols("x xd")
    m = sp.Symbol("m", positive=True)
    model = vcigen.Model(
        name="relativistic",
        q=[x],
        qdot=[xd],
        lagrangian=-m * sp.sqrt(1 - xd**2) - x,
        contacts={"wall": 1 - x},
        params={m: 2.0},
    )
    res = vcigen.build(model, backend="casadi").simulate([0.0], [0.9], 0.01, t_end=0.3, params={"m": 3.0})
    p = res.p[:, 0]
    np.testing.assert_allclose(res.v[:, 0], p / np.sqrt(9.0 + p**2), rtol=1e-14, atol=1e-15)
    assert res.v[0, 0] == pytest.approx(0.9, rel=1e-14)
