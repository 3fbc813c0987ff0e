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
the reference's rest angle, the same on both backends.
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
