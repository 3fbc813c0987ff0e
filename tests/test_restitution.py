"""Restitution (eq. 39, frictionless): an impact on contact j loses (1 - e^2)/2 (n.qdot)^2/(n.M^-1 n).

A ball dropped on a floor with coefficient e: each bounce leaves with e times the incoming
normal speed, so the flight times shrink by e and the bounces accumulate at the Zeno time
t_inf = t_1 + 2 e v_1 / (g (1 - e)); after it the ball rests on the floor (to O(h^2)) and
slides on with its horizontal momentum untouched.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
import sympy as sp
from hard_scenes import G, backend_param, c_backend_problem, simulator, zeno_time

import vcigen

BACKENDS = [backend_param("casadi"), backend_param("c")]
E = "e"


@pytest.fixture(scope="module", params=BACKENDS)
def sim(request) -> vcigen.Simulator:
    return simulator("ball", request.param)


@pytest.mark.parametrize("e", [0.5, 0.8])
def test_bounces_shrink_by_e_and_lose_the_normal_energy(sim, e):
    res = sim.simulate([0.0, 1.0], [0.3, 0.0], 0.001, n_impacts=8, params={E: e})
    t = np.array([im.t for im in res.impacts])
    flights = np.diff(t)
    np.testing.assert_allclose(flights[1:] / flights[:-1], e, rtol=2e-3)
    v1 = math.sqrt(2 * G)  # normal speed at the first impact (dropped from height 1)
    assert t[0] == pytest.approx(v1 / G, abs=1e-6)
    loss = np.array([im.energy_before - im.energy_after for im in res.impacts])
    assert loss[0] == pytest.approx((1 - e * e) / 2 * v1 * v1, rel=1e-6)
    np.testing.assert_allclose(loss[1:] / loss[:-1], e * e, rtol=5e-3)
    # frictionless: the horizontal momentum goes through every impact untouched
    assert np.all(res.p[:, 0] == 0.3)


def test_the_ball_comes_to_rest_at_the_zeno_time_and_slides_on(sim):
    e, h = 0.5, 0.001
    res = sim.simulate([0.0, 1.0], [0.3, 0.0], h, t_end=2.0, params={E: e})
    t_inf = zeno_time(e)
    late = res.t > t_inf + 0.05
    assert np.max(res.q[late, 1]) <= G * h * h  # on the floor, to O(h^2)
    assert np.min(res.q[:, 1]) >= -1e-12  # and never below it
    # the vertical energy is gone: E_d is the sliding kinetic energy (plus O(g^2 h^2))
    np.testing.assert_allclose(res.energy[late[1:]], 0.3**2 / 2, atol=G * G * h * h)
    # before t_inf the bounces are separate; near it they merge into one impact per step
    before = [im for im in res.impacts if im.t < t_inf - 0.05]
    assert len(before) < 10
    assert abs(res.q[-1, 0] - 0.3 * 2.0) < 1e-9


def test_elastic_restitution_is_the_elastic_method(sim):
    """e = 1 (given or not) is bit for bit the elastic integrator."""
    given = sim.simulate([0.0, 1.0], [0.3, 0.0], 0.01, n_impacts=5, params={E: 1.0})
    plain = simulator("ball_elastic", sim.backend).simulate([0.0, 1.0], [0.3, 0.0], 0.01, n_impacts=5)
    np.testing.assert_array_equal(given.q, plain.q)
    np.testing.assert_array_equal(given.p, plain.p)
    assert [im.energy_after for im in given.impacts] == [im.energy_after for im in plain.impacts]


def test_c_and_casadi_agree_with_restitution():
    if c_backend_problem():
        pytest.skip(c_backend_problem())
    runs = [
        simulator("ball", b).simulate([0.0, 1.0], [0.3, 0.0], 0.002, n_impacts=10, params={E: 0.7})
        for b in ("c", "casadi")
    ]
    np.testing.assert_allclose(runs[0].q, runs[1].q, rtol=0, atol=1e-10)
    np.testing.assert_allclose(runs[0].energy, runs[1].energy, rtol=0, atol=1e-10)
    for a, b in zip(runs[0].impacts, runs[1].impacts):
        assert abs(a.t - b.t) <= 1e-10 and abs(a.energy_after - b.energy_after) <= 1e-10


@pytest.mark.parametrize(
    "kwargs,match",
    [
        ({"restitution": {"wall": 0.5}}, "not a contact"),
        ({"restitution": {"floor": 1.5}}, r"must lie in \[0, 1\]"),
        ({"restitution": {"floor": sp.Symbol("k")}}, "not a parameter"),
    ],
)
def test_bad_restitution_is_refused(kwargs, match):
    x, y, xd, yd = sp.symbols("x y xd yd")
    with pytest.raises(ValueError, match=match):
        vcigen.Model(
            name="ball",
            q=[x, y],
            qdot=[xd, yd],
            lagrangian=(xd**2 + yd**2) / 2 - G * y,
            contacts={"floor": y},
            **kwargs,
        )


def test_a_restitution_parameter_out_of_range_is_refused_at_run_time(sim):
    with pytest.raises(ValueError, match=r"restitution of 'floor' is 1.2 at these parameters"):
        sim.simulate([0.0, 1.0], [0.3, 0.0], 0.01, n_impacts=1, params={E: 1.2})
