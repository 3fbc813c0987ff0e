"""Bilateral constraints in maximal coordinates (issue 9, item 4), both backends, against scipy.

A double pendulum as two bobs on two rods (an open chain) and a parallelogram four-bar linkage as two
bobs on three bars between two fixed pivots (a closed chain: four coordinates, three constraints, one
degree of freedom; ``examples/contact/four_bar.py``'s model). Their references are scipy's (1e-12) on
the angles: the double pendulum's own equations, and for the parallelogram the pendulum of mass 2 that
both bobs ride (the coupler stays level, so each bob is at ``(cos θ, sin θ)`` from its pivot), reflected
at the floor. Before stop 40 a model of two or more constraints and no contact did not compile in C
(``-Werror=maybe-uninitialized`` on ``<model>_chain_impact``'s restitutions, of which it has none).
"""

from __future__ import annotations

import math
import sys
from functools import cache
from pathlib import Path

import numpy as np
import pytest
import sympy as sp
from hard_scenes import BACKENDS, G
from scipy.integrate import solve_ivp

import vcigen

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "examples" / "contact"))
import four_bar as example  # noqa: E402 - examples/contact/four_bar.py: its model, floor y_b >= FLOOR, e

FLOOR = example.FLOOR


def double_pendulum() -> vcigen.Model:
    """Unit bobs on unit rods, the first pivoted at the origin: q = (x1, y1, x2, y2)."""
    x1, y1, x2, y2, u1, v1, u2, v2 = sp.symbols("x1 y1 x2 y2 u1 v1 u2 v2")
    return vcigen.Model(
        name="double_cartesian",
        q=[x1, y1, x2, y2],
        qdot=[u1, v1, u2, v2],
        lagrangian=(u1**2 + v1**2 + u2**2 + v2**2) / 2 - G * (y1 + y2),
        constraints={"rod1": x1**2 + y1**2 - 1, "rod2": (x2 - x1) ** 2 + (y2 - y1) ** 2 - 1},
    )


@cache
def sim(name: str, backend: str) -> vcigen.Simulator:
    return vcigen.build({"double": double_pendulum, "four_bar": example.model}[name](), backend=backend)


def _angles(t, y):
    """The double pendulum on its angles from the downward vertical (unit masses and lengths)."""
    a, b, wa, wb = y
    d = a - b
    den = 3 - math.cos(2 * d)
    acc_a = (
        -3 * G * math.sin(a) - G * math.sin(a - 2 * b) - 2 * math.sin(d) * (wb**2 + wa**2 * math.cos(d))
    ) / den
    acc_b = 2 * math.sin(d) * (2 * wa**2 + 2 * G * math.cos(a) + wb**2 * math.cos(d)) / den
    return [wa, wb, acc_a, acc_b]


def _bobs(a, b, wa, wb):
    x1, y1 = math.sin(a), -math.cos(a)
    u1, v1 = wa * math.cos(a), wa * math.sin(a)
    return [x1, y1, x1 + math.sin(b), y1 - math.cos(b)], [
        u1,
        v1,
        u1 + wb * math.cos(b),
        v1 + wb * math.sin(b),
    ]


@pytest.mark.parametrize("backend", BACKENDS)
def test_a_double_pendulum_on_two_rods_follows_its_angles_to_second_order(backend):
    """Two rods held as constraints over 2 s (a swing of both): the bobs meet scipy's angles to O(h^2) and
    stay on both rods to round-off."""
    start, t_end = (1.0, -0.5, 0.0, 1.0), 2.0
    exact = solve_ivp(_angles, (0, t_end), start, dense_output=True, rtol=1e-12, atol=1e-12)
    errors = []
    for h in (0.01, 0.005):
        res = sim("double", backend).simulate(*_bobs(*start), h, t_end=t_end)
        ref = np.array([_bobs(*exact.sol(t))[0] for t in res.t])
        errors.append(np.abs(res.q - ref).max())
        x1, y1, x2, y2 = res.q.T
        assert (
            np.abs(x1**2 + y1**2 - 1).max() < 1e-12
            and np.abs((x2 - x1) ** 2 + (y2 - y1) ** 2 - 1).max() < 1e-12
        )
    assert errors[0] < 2e-3 and errors[0] / errors[1] > 3.8  # 1.27e-3, 3.17e-4


def _pendulum(t, y):
    """The four-bar's angle: a pendulum of mass 2 on the bars' unit length."""
    return [y[1], -G * math.cos(y[0])]


def _four_bar_start(theta: float, omega: float):
    c, s = math.cos(theta), math.sin(theta)
    return [c, s, 2 + c, s], [-omega * s, omega * c] * 2


@pytest.mark.parametrize("backend", BACKENDS)
def test_a_parallelogram_four_bar_swings_as_its_pendulum_off_an_elastic_floor(backend):
    """The closed chain over 3 s, bouncing four times on the floor under B: its angle meets the pendulum's
    (scipy, events located, each reflected) to O(h^2), every bar's length kept to round-off."""
    theta0, omega0, t_end = -0.5, 1.0, 3.0
    hit = lambda t, y: math.sin(y[0]) - FLOOR  # noqa: E731
    hit.terminal, hit.direction = True, -1
    pieces, t0, y0 = [], 0.0, [theta0, omega0]
    while t0 < t_end:
        sol = solve_ivp(_pendulum, (t0, t_end), y0, events=hit, dense_output=True, rtol=1e-12, atol=1e-12)
        pieces.append((t0, sol.t[-1], sol.sol))
        if sol.status != 1:
            break
        t0, y0 = sol.t_events[0][0], [sol.y_events[0][0][0], -sol.y_events[0][0][1]]
    errors = []
    for h in (0.01, 0.005):
        res = sim("four_bar", backend).simulate(
            *_four_bar_start(theta0, omega0), h, t_end=t_end, params={"e": 1.0}
        )
        assert len(res.impacts) == len(pieces) - 1 == 4
        exact = np.array([next(f(t)[0] for a, b, f in pieces if a <= t <= b) for t in res.t])
        errors.append(np.abs(np.arctan2(res.q[:, 1], res.q[:, 0]) - exact).max())
        xb, yb, xc, yc = res.q.T
        for bar in (xb**2 + yb**2 - 1, (xc - xb) ** 2 + (yc - yb) ** 2 - 4, (xc - 2) ** 2 + yc**2 - 1):
            assert np.abs(bar).max() < 1e-12
        assert yb.min() >= FLOOR - 1e-12
    assert errors[0] < 1e-3 and errors[0] / errors[1] > 3.8  # 5.85e-4, 1.46e-4


@pytest.mark.parametrize("e", [0.0, 0.5])
@pytest.mark.parametrize("backend", BACKENDS)
def test_a_four_bar_comes_to_rest_on_the_floor_pressed_by_twice_its_weight(backend, e):
    """With ``e < 1`` the bounces end held on the floor: at rest there, and by virtual work (``N δy_b = g
    (δy_b + δy_c)``, ``δy_b = δy_c``) the floor pushes with ``2 g``."""
    res = sim("four_bar", backend).simulate(*_four_bar_start(-0.5, 1.0), 0.01, t_end=4.0, params={"e": e})
    rest = math.sqrt(1 - FLOOR**2)
    assert res.impacts[-1].kind == "plastic" and res.active[-1, 0]
    assert (
        np.abs(res.q[-1] - [rest, FLOOR, 2 + rest, FLOOR]).max() < 1e-12 and np.abs(res.v[-1]).max() < 1e-12
    )
    assert abs(res.contact_force[-1, 0] - 2 * G) < 1e-9 * G
    assert res.q[:, 1].min() >= FLOOR - 1e-12


@pytest.mark.parametrize("backend", BACKENDS)
def test_a_double_pendulums_tangent_to_its_start_velocity_meets_finite_differences(backend):
    """``simulate(sensitivities=True)`` on the two rods (in C a model of its own, which did not compile
    before stop 40 either): ``d q_N / d v0`` along a velocity tangent to both rods against central
    differences of two runs (``v0 ± ε δ`` stays tangent: the rods' velocity condition is linear in it)."""
    q0, v0 = _bobs(1.0, -0.5, 0.0, 1.0)
    x1, y1, x2, y2 = q0
    delta = np.array([y1, -x1, y2, -x2])  # both rods turning as one about the pivot
    assert abs(delta[:2] @ [x1, y1]) < 1e-15 and abs((delta[2:] - delta[:2]) @ [x2 - x1, y2 - y1]) < 1e-15
    s, eps = sim("double", backend), 1e-6
    res = s.simulate(q0, v0, 0.01, t_end=0.5, sensitivities=True)
    ahead = s.simulate(q0, np.add(v0, eps * delta), 0.01, t_end=0.5).q[-1]
    behind = s.simulate(q0, np.subtract(v0, eps * delta), 0.01, t_end=0.5).q[-1]
    tangent = res.sensitivity[-1, :4, 4:8] @ delta
    assert not res.sensitivity_breaks  # no event: the tangent goes through every step
    np.testing.assert_allclose(
        tangent, (ahead - behind) / (2 * eps), rtol=0, atol=1e-7 * np.abs(tangent).max()
    )
