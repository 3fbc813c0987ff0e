"""The public API of shared/API.md, exactly as written there."""

import numpy as np
import pytest
import sympy as sp
from scenes import simulator

import vcigen


def test_api_example_as_written():
    x, y, xd, yd = sp.symbols("x y xd yd")
    m, g = sp.symbols("m g", positive=True)
    model = vcigen.Model(
        name="particle",
        q=[x, y],
        qdot=[xd, yd],
        lagrangian=m / 2 * (xd**2 + yd**2) - m * g * y,
        contacts={"floor": y},
        params={m: 1.0, g: 9.81},
    )
    sim = vcigen.build(model, backend="casadi", rule="trapezoid")
    res = sim.simulate(q0=[0.0, 1.0], v0=[-2.0, 0.0], h=0.01, t_end=5.0, params={g: 9.81})
    n_steps = 500
    assert res.t.shape == (n_steps + 1,) and res.q.shape == (n_steps + 1, 2)
    assert res.p.shape == (n_steps + 1, 2) and res.energy.shape == (n_steps,)
    np.testing.assert_allclose(res.t, 0.01 * np.arange(n_steps + 1), rtol=0, atol=1e-12)
    np.testing.assert_allclose(res.p[0], [-2.0, 0.0])  # p_0 = dL/dqdot at (q0, v0)
    imp = res.impacts[0]
    assert imp.contact == "floor" and 0 <= imp.alpha <= 1 and imp.impulse > 0
    assert imp.q.shape == (2,) and imp.t == pytest.approx(0.01 * imp.step + 0.01 * imp.alpha)


@pytest.mark.parametrize("key", ["symbol", "name"])
def test_params_override_changes_the_physics(key):
    sim = simulator("particle")
    g = next(s for s in sim.model.defaults if s.name == "g")
    res = sim.simulate(
        q0=[0.0, 1.0], v0=[0.0, 0.0], h=0.01, n_impacts=1, params={g if key == "symbol" else "g": 4.0}
    )
    assert res.impacts[0].t == pytest.approx(np.sqrt(2 / 4.0), abs=1e-12)


def test_n_impacts_stops_after_that_many():
    res = simulator("particle").simulate(q0=[0.0, 1.0], v0=[-2.0, 0.0], h=0.01, n_impacts=3)
    assert res.n_impacts == 3
    assert res.impacts[-1].step == res.t.size - 2  # stopped right after the step of impact 3
    both = simulator("particle").simulate(q0=[0.0, 1.0], v0=[-2.0, 0.0], h=0.01, n_impacts=100, t_end=1.0)
    assert both.t[-1] == pytest.approx(1.0) and both.n_impacts == 1  # impacts at 0.45 s and 1.35 s


def test_dynamicsymbols_and_general_lagrangian():
    """dynamicsymbols without qdot; a Lagrangian that is not T - V with constant M."""
    from sympy.physics.mechanics import dynamicsymbols

    th, r = dynamicsymbols("theta r")
    t = sp.Symbol("t")
    k = sp.Symbol("k", positive=True)
    lag = (r.diff(t) ** 2 + r**2 * th.diff(t) ** 2) / 2 - k * r**2 / 2  # polar coordinates
    model = vcigen.Model(name="polar", q=[th, r], lagrangian=lag, contacts={"rim": 1 - r}, params={k: 1.0})
    res = vcigen.build(model).simulate(q0=[0.0, 0.5], v0=[2.0, 1.0], h=0.01, n_impacts=5)
    assert res.n_impacts == 5
    # Angular momentum p_theta = r^2 theta' is conserved (theta is cyclic, the rim round).
    assert np.max(np.abs(res.p[:, 0] - res.p[0, 0])) < 1e-12
    assert res.q[:, 1].max() <= 1 + 1e-9


def test_csv_roundtrip(tmp_path):
    res = simulator("particle").simulate(q0=[0.0, 1.0], v0=[-2.0, 0.0], h=0.01, t_end=1.0)
    data = np.genfromtxt(res.to_csv(tmp_path / "r.csv"), delimiter=",", names=True)
    np.testing.assert_array_equal(data["y"], res.q[:, 1])
    imp = np.genfromtxt(res.impacts_to_csv(tmp_path / "i.csv"), delimiter=",", names=True, dtype=None)
    assert imp.size == res.n_impacts
