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
from collections import Counter
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


LOW = -1.5  # the floor under the double pendulum's second bob (double_on_floor)


def double_on_floor() -> vcigen.Model:
    """:func:`double_pendulum` with its second bob on a floor ``y2 >= LOW`` (restitution ``e``)."""
    m, e = double_pendulum(), sp.Symbol("e", nonnegative=True)
    return vcigen.Model(
        name="double_floor",
        q=m.q,
        qdot=m.qdot,
        lagrangian=m.lagrangian,
        constraints=m.constraints,
        contacts={"floor": m.q[3] - LOW},
        params={e: 0.0},
        restitution={"floor": e},
    )


@cache
def sim(name: str, backend: str) -> vcigen.Simulator:
    models = {"double": double_pendulum, "double_floor": double_on_floor, "four_bar": example.model}
    return vcigen.build(models[name](), backend=backend)


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


def _rows(q, u, floor: bool):
    """The double pendulum's rods' gradients ``G`` and curvatures ``u . Hess . u`` (with ``floor`` the floor's
    row of the second bob too)."""
    (x1, y1, x2, y2), (u1, v1, u2, v2) = q, u
    g = [[2 * x1, 2 * y1, 0, 0], [2 * (x1 - x2), 2 * (y1 - y2), 2 * (x2 - x1), 2 * (y2 - y1)]]
    curv = [2 * (u1**2 + v1**2), 2 * ((u2 - u1) ** 2 + (v2 - v1) ** 2)]
    return np.array(g + [[0, 0, 0, 1]] * floor, float), np.array(curv + [0.0] * floor)


def _held_rows(y, floor: bool):
    """``qddot`` of the double pendulum at the state ``y = (q, qdot)`` under its rods' forces (and with
    ``floor`` the floor's, the second bob held on it), and those forces: ``G qddot + curv = 0``, ``qddot = f
    + G^T lam`` (unit masses)."""
    g, curv = _rows(y[:4], y[4:], floor)
    f = np.array([0.0, -G, 0.0, -G])
    lam = np.linalg.solve(g @ g.T, -(g @ f + curv))
    return f + g.T @ lam, lam


@pytest.mark.parametrize("backend", BACKENDS)
def test_a_double_pendulums_bob_stopped_on_the_floor_by_e_0_is_held_there_at_once(backend):
    """Released from rest, the second bob lands on the floor with ``e = 0`` and slides on it, held, pressed
    by its rod (the floor's force stays above 0.6 g in the reference). Reference (scipy, 1e-12, events
    located): the free pendulum to the landing, the velocity projected onto the rods and the floor (``e =
    0``), then the pendulum with the bob held on the floor. The landing time and the bobs meet it to
    O(h^2). The landing is one plastic impact: the bob's normal speed along its circle pulls it up at the
    incoming velocity, and once stopped its rod presses it in (``HeldImpacts._stopped_pressed``). Before stop
    50 the landing logged an impact that stopped the bob and a second one, plastic, that held it at the same
    instant; before stop 43 the held-row test read the rods' forces of the step before the landing (they
    pulled the bob up), and CasADi logged three bounces of 1e-8 then the plastic impact."""
    q0 = _bobs(-0.8, -2.0, 0.0, 0.0)[0]
    land = lambda t, y: y[3] - LOW  # noqa: E731
    land.terminal, land.direction = True, -1
    fall = solve_ivp(
        lambda t, y: [*y[4:], *_held_rows(y, False)[0]],
        (0, 1),
        q0 + [0.0] * 4,
        events=land,
        rtol=1e-12,
        atol=1e-12,
    )
    t_land, y_land = fall.t_events[0][0], fall.y_events[0][0]
    g = _rows(y_land[:4], y_land[4:], True)[0]  # e = 0: the velocity projected onto the rods and the floor
    v_held = y_land[4:] - g.T @ np.linalg.solve(g @ g.T, g @ y_land[4:])
    slide = solve_ivp(
        lambda t, y: [*y[4:], *_held_rows(y, True)[0]],
        (t_land, 2.0),
        [*y_land[:4], *v_held],
        dense_output=True,
        rtol=1e-12,
        atol=1e-12,
    )
    assert min(_held_rows(slide.sol(t), True)[1][2] for t in np.linspace(t_land, 2.0, 200)) > 0.6 * G
    errors = []
    for h in (0.01, 0.005):
        res = sim("double_floor", backend).simulate(q0, [0.0] * 4, h, t_end=2.0)
        assert [i.kind for i in res.impacts] == ["plastic"] and not res.liftoffs
        assert abs(res.impacts[0].t - t_land) < 0.5 * h * h
        after = res.t > t_land + h
        assert res.active[after, 0].all() and np.abs(res.q[after, 3] - LOW).max() < 1e-13
        errors.append(np.abs(res.q[after] - slide.sol(res.t[after])[:4].T).max())
    assert errors[0] < 2e-4 and errors[0] / errors[1] > 3.8  # 1.44e-4, 3.60e-5


@pytest.mark.parametrize("backend", BACKENDS)
def test_a_bob_bouncing_below_any_resolution_is_held_after_four_bounces_in_a_step(backend):
    """The landing above with ``e = 0.5`` and ``Tolerances(rest=1e-6)``: no bounce is below the resolution,
    so the bob bounces on, its flights shrinking by ``e`` (to 1e-5 at the end: the rods' forces barely change
    over them), until a step's held chain has met it ``BOUNCE_CYCLES`` (4) times and holds it at the next
    (MATH.md: Zeno ends in sustained contact after a few impacts a step), within the last flight of where the
    bounces accumulate (``t_n + f_n e / (1 - e)``). No impact adds energy; held after, on the floor. The
    default resolution holds it 0.04 s sooner, at its flight below it: the same end to O(h)."""
    q0, h, e = _bobs(-0.8, -2.0, 0.0, 0.0)[0], 0.01, 0.5
    s = vcigen.build(double_on_floor(), backend=backend, tol=vcigen.Tolerances(rest=1e-6))
    res = s.simulate(q0, [0.0] * 4, h, t_end=2.0, params={"e": e})
    per_step = Counter(i.step for i in res.impacts)
    last = res.impacts[-1]
    assert max(per_step.values()) == per_step[last.step] == 5 and last.kind == "plastic"
    assert [i.kind for i in res.impacts[:-1]] == ["restitution"] * (len(res.impacts) - 1)
    times = np.array([i.t for i in res.impacts])
    flights = np.diff(times[:-1])
    assert flights[-1] / flights[-2] == pytest.approx(0.5, rel=1e-5)
    assert abs(last.t - (times[-2] + flights[-1] * e / (1 - e))) < flights[-1]
    assert all(i.energy_after <= i.energy_before for i in res.impacts)
    after = res.t > last.t
    assert res.active[after, 0].all() and np.abs(res.q[after, 3] - LOW).max() < 1e-13 and not res.liftoffs
    default = sim("double_floor", backend).simulate(q0, [0.0] * 4, h, t_end=2.0, params={"e": e})
    assert default.impacts[-1].kind == "plastic" and 0 < last.t - default.impacts[-1].t < 5 * h
    assert np.abs(default.q[-1] - res.q[-1]).max() < 0.1 * h


@pytest.mark.parametrize("backend", BACKENDS)
def test_a_held_step_that_cannot_keep_both_rods_names_them(backend):
    """At ``h = 0.6`` the double pendulum's first held step moves the bobs farther than the rods allow: the
    ``SolverError`` at step 0 names the rows held, in row order, the same on both backends."""
    with pytest.raises(vcigen.SolverError, match="sustained solve failed") as err:
        sim("double_floor", backend).simulate(_bobs(-0.8, -2.0, 0.0, 0.0)[0], [0.0] * 4, 0.6, t_end=5.0)
    assert err.value.step == 0 and err.value.phase == "sustained"
    assert str(err.value).endswith(vcigen.errors.HELD_NO_ROOT + vcigen.errors.HELD_ROWS + "rod1, rod2")


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
