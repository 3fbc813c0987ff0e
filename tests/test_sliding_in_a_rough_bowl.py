"""A particle sliding inside a rough circular bowl (MATH.md *Friction*: Coulomb's force in sustained contact
on a curved row), against scipy with event location.

The unit particle in the circle ``|q| = R`` (``R - |q| >= 0``, ``R = 1``), plastic, Coulomb friction ``mu``
along the arc (tangent ``R atan2(x, -y)``). Released at rest at ``theta0 = 1.2`` from the bottom it is held on
the circle from the start and slides, the normal force ``N = m (R thetad^2 + g cos theta)`` carrying the
centripetal term, so ``R thetadd = -g sin theta - mu N / m sign(thetad)``. It turns where ``thetad = 0``
and, where ``tan |theta| <= mu``, stays there (at ``mu = 0.2`` after one swing and a half: at t = 2.054,
theta = 0.1522). The reference integrates each slide with ``scipy.integrate.solve_ivp`` (rtol 1e-12) to its
turn (an event). vcigen's angle at every grid point is within 1.40 h^2 of it (h = 0.01, 0.005, 0.0025; the
largest error at t = 0.67, in the first slide), it never leaves the circle, and it rests within 0.0627 h^2 of
the reference's rest angle, the same on both backends. And a particle sliding off a rough dome: its lift-off
where the normal force vanishes, against scipy's event, at order 2.
"""

from __future__ import annotations

import math
from functools import cache

import numpy as np
import pytest
import sympy as sp
from hard_scenes import BACKENDS, G
from scipy.integrate import solve_ivp

import vcigen

R, MU, THETA0, T_END = 1.0, 0.2, 1.2, 3.0


def model() -> vcigen.Model:
    x, y, xd, yd = sp.symbols("x y xd yd")
    return vcigen.Model(
        name="rough_bowl_slide",
        q=[x, y],
        qdot=[xd, yd],
        lagrangian=(xd**2 + yd**2) / 2 - G * y,
        contacts={"bowl": R - sp.sqrt(x**2 + y**2)},
        restitution={"bowl": 0.0},
        friction={"bowl": (MU, R * sp.atan2(x, -y))},
    )


@cache
def reference() -> tuple[list, float, float]:
    """The slides' dense solutions ``[(t0, t1, sol)]``, and the time and angle where the particle stops."""
    t, state, pieces = 0.0, [THETA0, 0.0], []
    while abs(math.tan(state[0])) > MU:
        sgn = -math.copysign(1.0, state[0])  # from rest, it slides toward the bottom

        def rhs(_t, s, sgn=sgn):
            return [s[1], (-G * math.sin(s[0]) - MU * (R * s[1] ** 2 + G * math.cos(s[0])) * sgn) / R]

        def turn(_t, s):
            return s[1]

        turn.terminal, turn.direction = True, -sgn
        sol = solve_ivp(rhs, (t, T_END), state, rtol=1e-12, atol=1e-13, events=turn, dense_output=True)
        assert sol.t_events[0].size, "the reference slides to its turn within T_END"
        t_turn = float(sol.t_events[0][0])
        pieces.append((t, t_turn, sol.sol))
        t, state = t_turn, [float(sol.y_events[0][0][0]), 0.0]
    return pieces, t, state[0]


def reference_angle(t: float) -> float:
    pieces, t_stop, theta_stop = reference()
    for t0, t1, sol in pieces:
        if t0 <= t <= t1:
            return float(sol(t)[0])
    return theta_stop


@cache
def run(backend: str, h: float) -> vcigen.Result:
    q0 = [R * math.sin(THETA0), -R * math.cos(THETA0)]
    return vcigen.build(model(), backend=backend).simulate(q0, [0.0, 0.0], h, t_end=T_END)


def test_the_reference_turns_twice_and_stops_inside_the_friction_angle() -> None:
    pieces, t_stop, theta_stop = reference()
    assert len(pieces) == 2 and abs(math.tan(theta_stop)) <= MU < abs(math.tan(pieces[1][2](pieces[1][0])[0]))
    assert 2.0 < t_stop < 2.1


@pytest.mark.parametrize("backend", BACKENDS)
def test_a_particle_slides_in_a_rough_bowl_at_order_2_and_rests_where_scipy_does(backend: str) -> None:
    _, t_stop, theta_stop = reference()
    errors = []
    for h in (0.01, 0.005):
        res = run(backend, h)
        assert not res.impacts and not res.liftoffs and res.active.all()
        assert np.abs(np.hypot(res.q[:, 0], res.q[:, 1]) - R).max() < 1e-12
        theta = np.arctan2(res.q[:, 0], -res.q[:, 1])
        errors.append(max(abs(a - reference_angle(float(t))) for a, t in zip(theta, res.t)))
        assert abs(theta[-1] - theta_stop) < 0.07 * h * h and np.abs(res.v[-1]).max() < 1e-12
    assert errors[0] < 1.5 * 0.01**2 and errors[0] / errors[1] > 3.9


def dome() -> vcigen.Model:
    """The unit particle on the rough dome ``|q| >= R`` (``mu``), the tangent the arc ``R atan2(x, y)``."""
    x, y, xd, yd = sp.symbols("x y xd yd")
    return vcigen.Model(
        name="rough_dome_slide",
        q=[x, y],
        qdot=[xd, yd],
        lagrangian=(xd**2 + yd**2) / 2 - G * y,
        contacts={"dome": sp.sqrt(x**2 + y**2) - R},
        restitution={"dome": 0.0},
        friction={"dome": (MU, R * sp.atan2(x, y))},
    )


@pytest.mark.parametrize("backend", BACKENDS)
def test_a_particle_slides_off_a_rough_dome_where_its_normal_force_vanishes_at_order_2(backend: str) -> None:
    """Started on the dome at ``theta = 0.3`` from its top, moving down at ``thetad = 0.5``, held: ``R
    thetadd = g sin theta - mu (g cos theta - R thetad^2)``, and it leaves where ``N = m (g cos theta - R
    thetad^2)`` reaches 0 (scipy's event: t = 0.64028, theta = 0.96755). The lift-off is located 0.360 h^2
    late (h = 0.01, 0.005, 0.0025: ratios 4.000), the same on both backends."""

    def rhs(_t, s):
        return [s[1], (G * math.sin(s[0]) - MU * (G * math.cos(s[0]) - R * s[1] ** 2)) / R]

    def leaves(_t, s):
        return G * math.cos(s[0]) - R * s[1] ** 2

    leaves.terminal, leaves.direction = True, -1
    theta0, w0 = 0.3, 0.5
    sol = solve_ivp(rhs, (0.0, 5.0), [theta0, w0], rtol=1e-12, atol=1e-13, events=leaves)
    t_off = float(sol.t_events[0][0])
    sim = vcigen.build(dome(), backend=backend)
    q0 = [R * math.sin(theta0), R * math.cos(theta0)]
    v0 = [R * w0 * math.cos(theta0), -R * w0 * math.sin(theta0)]
    late = []
    for h in (0.01, 0.005, 0.0025):
        res = sim.simulate(q0, v0, h, t_end=t_off + 0.2)
        assert res.active[0].all() and not res.impacts and [j for _, j in res.liftoffs] == ["dome"]
        late.append(res.liftoffs[0][0] - t_off)
    assert 0 < late[0] < 0.37 * 0.01**2 and all(3.9 < a / b < 4.1 for a, b in zip(late, late[1:]))
