"""A double pendulum in its angles (a mass matrix that varies with ``q``) whose tip lands on, rests on, slides
along and leaves a rough floor (MATH.md *Sustained contact* and *Friction*), against scipy and statics.

Unit masses and rods, angles from the downward vertical, the pivot at the origin; the tip's height above the
floor ``y = FLOOR`` is the contact, its abscissa the friction's tangent.

* **Held on the floor**: the tip started on the floor with a velocity along it slides (``mu = 0``, ``0.5``)
  until it stops or lifts off; scipy integrates the index-1 DAE (``M a = -C + (J_n - mu sgn J_t) lam``,
  ``J_n a + dJ_n = 0``, DOP853 at rtol 1e-12) with the lift-off (``lam = 0``) and the stop (``J_t v = 0``)
  as events. vcigen's ``q`` stays within ``2 h^2`` of it (second order), the lift-off time within ``0.6 h^2``.
* **A landing at e = 0**: swung down onto the floor, the tip's own normal speed pulls it up at the impact
  (``d2 phi/dt2 > 0`` at the incoming velocity), but once that speed is gone gravity presses it in: the
  landing is one plastic impact, the tip sticks (``mu = 0.5``) and the pendulum rests on it with the normal
  force the statics give (two equations, the tip's two forces). Before the fix the landing was tested at the
  incoming velocity: (48a) had no root, the impact took the continuous law as *grazing*, a restart followed,
  and the tangent broke there. Now the tangent goes through the landing and equals central differences.
* **A landing at e = 0 stopped by friction**: here even the velocity a frictionless plastic impact leaves
  does not press the tip in (its tangential speed pulls it up), but Coulomb's impulse stops the tip too, and
  stopped it is pressed. Where (48a) has no root, "pressed in" is also read at the velocity the continuous
  law (with Coulomb's impulse) leaves; the landing is one plastic impact, as above.
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

FLOOR = -1.4
T1, T2, D1, D2 = sp.symbols("t1 t2 d1 d2")
MU, E = sp.symbols("mu e")
X1, Y1 = sp.sin(T1), -sp.cos(T1)
X2, Y2 = X1 + sp.sin(T2), Y1 - sp.cos(T2)
Q, QD = sp.Matrix([T1, T2]), sp.Matrix([D1, D2])
_V1, _V2 = sp.Matrix([X1, Y1]).jacobian(Q) * QD, sp.Matrix([X2, Y2]).jacobian(Q) * QD
LAGRANGIAN = (_V1.dot(_V1) + _V2.dot(_V2)) / 2 - G * (Y1 + Y2)

# landings at e = 0, mu = 0.5 that the incoming velocity does not press in: swung down onto the floor, the
# tip's normal speed pulling it up at the impact ("pulled up"); and one that the velocity a frictionless
# plastic impact leaves does not press either, its tangential speed pulling it up, but Coulomb's impulse stops
# it ("stopped")
LANDINGS = {
    "pulled up": ([-1.80394644, -0.44161886], [-0.80376566, 0.14088473]),
    "stopped": ([1.9833499167701847, -1.6379564551951975], [2.319657588962981, -0.8007779233815802]),
}


@cache
def simulator(backend: str) -> vcigen.Simulator:
    model = vcigen.Model(
        name="dp_floor",
        q=[T1, T2],
        qdot=[D1, D2],
        lagrangian=LAGRANGIAN,
        contacts={"tip": Y2 - FLOOR},
        restitution={"tip": E},
        friction={"tip": (MU, X2)},
        params={MU: 0.5, E: 0.0},
    )
    return vcigen.build(model, backend=backend)


@cache
def _terms():
    mass = sp.hessian(LAGRANGIAN, QD)
    rest = sp.Matrix([LAGRANGIAN]).jacobian(QD).jacobian(Q) * QD - sp.Matrix([LAGRANGIAN]).jacobian(Q).T
    jn, jt = sp.Matrix([Y2]).jacobian(Q), sp.Matrix([X2]).jacobian(Q)
    djn = (jn * QD).jacobian(Q) * QD
    grad_v = sp.Matrix([G * (Y1 + Y2)]).jacobian(Q)
    return sp.lambdify((T1, T2, D1, D2), [mass, rest, jn, jt, djn, grad_v], "numpy")


def terms(q, v):
    return [np.array(a, float) for a in _terms()(*q, *v)]


def on_floor(a1: float, speed: float) -> tuple[list[float], np.ndarray]:
    """The tip on the floor (``t1 = a1``, the elbow to the right of the tip's plumb) moving along it."""
    a2 = math.acos(-FLOOR - math.cos(a1))
    jn = terms([a1, a2], [0.0, 0.0])[2].ravel()
    v = np.array([-jn[1], jn[0]])
    return [a1, a2], v / np.linalg.norm(v) * speed


def held_reference(q0, v0, mu: float, t_end: float):
    """scipy's solution of the tip held on the floor, sliding with Coulomb friction; stops at the lift-off
    (``lam`` reaching 0) or where the tip stops."""
    mass, _, _, jt, _, _ = terms(q0, v0)
    sgn = math.copysign(1.0, float(jt.ravel() @ v0))

    def solve(y):
        mass, rest, jn, jt, djn, _ = terms(y[:2], y[2:])
        a = np.zeros((3, 3))
        a[:2, :2] = mass
        a[:2, 2] = -(jn.ravel() - mu * sgn * jt.ravel())
        a[2, :2] = jn.ravel()
        return np.linalg.solve(a, np.concatenate([-rest.ravel(), [-float(djn.ravel()[0])]]))

    def lift(_t, y):
        return solve(y)[2]

    def stop(_t, y):
        return float(terms(y[:2], y[2:])[3].ravel() @ y[2:])

    lift.terminal = stop.terminal = True
    lift.direction = -1
    return solve_ivp(
        lambda _t, y: [*y[2:], *solve(y)[:2]],
        (0.0, t_end),
        [*q0, *v0],
        method="DOP853",
        rtol=1e-12,
        atol=1e-13,
        events=[lift, stop],
        dense_output=True,
    )


@pytest.mark.parametrize("backend", BACKENDS)
@pytest.mark.parametrize(
    ("mu", "a1", "speed", "lifts"),
    [(0.0, 0.3, 1.0, False), (0.5, 0.3, 1.0, False), (0.3, -0.5, 3.0, False), (0.2, 0.2, 6.0, True)],
)
def test_the_tip_held_on_the_floor_follows_the_dae(backend, mu, a1, speed, lifts):
    """Second order against scipy up to the event, and the lift-off (where there is one) at scipy's time."""
    q0, v0 = on_floor(a1, speed)
    ref = held_reference(q0, v0, mu, 3.0)
    t_event = float(ref.t[-1])
    assert (len(ref.t_events[0]) == 1) == lifts and t_event < 3.0
    sim = simulator(backend)
    errs, lift_errs = [], []
    for h in (0.01, 0.005, 0.0025):
        res = sim.simulate(q0=q0, v0=v0, h=h, t_end=t_event, params={"mu": mu}, progress=False)
        keep = res.t <= 0.98 * t_event
        assert res.active[keep, 0].all() and not res.impacts[: int(lifts)] or lifts
        err = np.abs(res.q[keep] - ref.sol(res.t[keep])[:2].T).max()
        errs.append(err)
        assert err <= 2.0 * h * h, (h, err)
        if lifts:
            assert res.liftoffs and res.liftoffs[0][1] == "tip"
            lift_errs.append(abs(res.liftoffs[0][0] - t_event))
            assert lift_errs[-1] <= 0.6 * h * h, (h, lift_errs[-1])
        else:
            assert not res.liftoffs and not res.impacts
    assert errs[0] / errs[2] > 14.0  # second order: 16 from h to h/4


def _landing(backend: str, q0, v0, mu: float = 0.5, sensitivities: bool = False):
    params = {"mu": mu, "e": 0.0}
    return simulator(backend).simulate(
        q0=q0, v0=v0, h=0.005, t_end=1.5, params=params, progress=False, sensitivities=sensitivities
    )


@pytest.mark.parametrize("backend", BACKENDS)
@pytest.mark.parametrize("landing", LANDINGS)
def test_a_landing_not_pressed_coming_in_is_plastic_and_rests_on_the_statics(backend, landing):
    res = _landing(backend, *LANDINGS[landing])
    (imp,) = res.impacts
    assert imp.kind == "plastic" and imp.contact == "tip" and imp.impulse > 1.0
    assert res.stats["jump_fallbacks"] == 0 and res.stats["impacts_grazing"] == 0
    # the tip's normal speed pulled it up at the impact; without it gravity presses it in
    mass, rest, jn, _, djn, _ = terms(imp.q, [0.0, 0.0])
    k = imp.step
    v_in = (res.q[k] - res.q[k - 1]) / 0.005
    mass, rest, jn, _, djn, _ = terms(imp.q, v_in)
    assert float(jn.ravel() @ np.linalg.solve(mass, -rest.ravel()) + djn.ravel()[0]) > 1.0
    # it sticks where it landed and rests there: the tip's two forces hold the statics
    after = res.t > imp.t + 0.01
    assert res.active[after, 0].all() and not res.liftoffs
    assert np.abs(res.q[after] - res.q[-1]).max() <= 1e-12
    assert abs(-math.cos(res.q[-1][0]) - math.cos(res.q[-1][1]) - FLOOR) <= 1e-12
    _, _, jn, jt, _, grad_v = terms(res.q[-1], [0.0, 0.0])
    normal, friction = np.linalg.solve(np.column_stack([jn.ravel(), jt.ravel()]), grad_v.ravel())
    assert abs(res.contact_force[-1, 0] - normal) <= 1e-9 * normal
    assert abs(friction) < 0.5 * normal


def _landing_end(backend: str, landing: str, column: int, name: str, step: float) -> np.ndarray:
    """``(q, p)`` at the end of the landing run with its start (``column`` of ``q0, v0``) or ``mu`` moved."""
    x, mu = [*LANDINGS[landing][0], *LANDINGS[landing][1]], 0.5
    if name == "mu":
        mu += step
    else:
        x[column] += step
    res = _landing(backend, x[:2], x[2:], mu)
    assert len(res.impacts) == 1
    return np.concatenate([res.q[-1], res.p[-1]])


@pytest.mark.parametrize("backend", BACKENDS)
@pytest.mark.parametrize("landing", LANDINGS)
def test_the_tangent_goes_through_the_landing(backend, landing):
    res = _landing(backend, *LANDINGS[landing], sensitivities=True)
    assert not res.sensitivity_breaks and np.isfinite(res.sensitivity[-1]).all()
    names = list(res.sensitivity_names)
    eps = 1e-6
    for column, name in enumerate(names[:4] + ["mu"]):
        ahead, behind = (_landing_end(backend, landing, column, name, step) for step in (eps, -eps))
        central = (ahead - behind) / (2.0 * eps)
        tangent = res.sensitivity[-1][:, names.index(name)]
        assert np.abs(central - tangent).max() <= 1e-6 * (1.0 + np.abs(central).max()), name
