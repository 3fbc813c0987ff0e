"""A double pendulum in maximal coordinates (two bobs, its rods bilateral constraints, held throughout) whose
tip lands on a rough floor (MATH.md *Sustained contact*: an impact while rows are held, and *Entry*).

Unit masses and rods, the pivot at the origin, the floor ``y = FLOOR``; the same pendulum as
``tests/test_double_pendulum_floor.py``, in the bobs' coordinates. Every impact of it is an impact while
held (the rods are), resolved by the impulse law (``SustainedSteps._chain_impact``), not by the jump (48).

* **A landing at e = 0 pulled up by its own normal speed**: the tip swings down onto the floor; at the
  incoming velocity its normal speed along the rods' circles pulls it up (``d2 phi/dt2 > 0``, computed here
  from the index-1 equations), once the impact has stopped it gravity presses it in. The landing is one
  plastic impact and the tip stays held: read at the incoming velocity alone it was stopped but let go, sank
  again at once and took a second, plastic impact of 2e-8 at the same instant (``_stopped_pressed``).
  Checked against statics: at rest, the tip's normal force is the one that, with the rods' tensions and the
  tip's friction, balances gravity (four equations, four forces).
* **A lift-off the map sinks after**: frictionless, the tip held on the floor slides until its force
  vanishes and lifts off; the exact tip rises as the cube of the time since, the map (its error of that
  order) sank 1e-7 below the floor in the rest of the step. The crossing located there met the tip moving
  away: six impacts of impulse 0 and two more lift-offs followed. Now such a crossing is a segment's end with
  no impulse and no log (``SustainedSteps._met_back``): one lift-off, the hop's landing the next impact.
  Against scipy (the pendulum with its rods, DOP853 at 1e-12, the landing, the lift-off and the hop's landing
  located): the lift-off time and the hop's landing at second order.
* **No jam without friction**: frictionless drops whose tip, released, sank and was met again at one instant
  until held on (``lifts_kept``) counted a Painleve jam and warned of it, on the backend that cycled; a jam
  needs sliding friction (``SustainedSteps._jam``).
"""

from __future__ import annotations

import math
import warnings
from functools import cache

import numpy as np
import pytest
import sympy as sp
from hard_scenes import BACKENDS, G
from scipy.integrate import solve_ivp

import vcigen

FLOOR = -1.4
X1, Y1, X2, Y2, U1, V1, U2, V2 = sp.symbols("x1 y1 x2 y2 u1 v1 u2 v2")
MU, E = sp.symbols("mu e")

# (t1, t2, d1, d2): angles from the downward vertical and their rates (tests/test_double_pendulum_floor.py)
LANDINGS = {
    "pulled up": (-1.80394644, -0.44161886, -0.80376566, 0.14088473),
    "stopped": (1.9833499167701847, -1.6379564551951975, 2.319657588962981, -0.8007779233815802),
}


def bobs(t1: float, t2: float, d1: float, d2: float) -> tuple[list[float], list[float]]:
    """``(q, v)`` of the bobs from the angles and their rates."""
    q = [math.sin(t1), -math.cos(t1), math.sin(t1) + math.sin(t2), -math.cos(t1) - math.cos(t2)]
    u1, w1 = d1 * math.cos(t1), d1 * math.sin(t1)
    return q, [u1, w1, u1 + d2 * math.cos(t2), w1 + d2 * math.sin(t2)]


@cache
def simulator(backend: str) -> vcigen.Simulator:
    model = vcigen.Model(
        name="dp_rods",
        q=[X1, Y1, X2, Y2],
        qdot=[U1, V1, U2, V2],
        lagrangian=(U1**2 + V1**2 + U2**2 + V2**2) / 2 - G * (Y1 + Y2),
        contacts={"tip": Y2 - FLOOR, "elbow": Y1 - FLOOR},
        constraints={"rod1": X1**2 + Y1**2 - 1, "rod2": (X2 - X1) ** 2 + (Y2 - Y1) ** 2 - 1},
        restitution={"tip": E, "elbow": E},
        friction={"tip": (MU, X2), "elbow": (MU, X1)},
        params={MU: 0.5, E: 0.0},
    )
    return vcigen.build(model, backend=backend)


def rods(q) -> np.ndarray:
    """The rods' gradients (rows) at ``q``."""
    x1, y1, x2, y2 = q
    return np.array([[2 * x1, 2 * y1, 0, 0], [-2 * (x2 - x1), -2 * (y2 - y1), 2 * (x2 - x1), 2 * (y2 - y1)]])


def tip_accel(q, v) -> float:
    """``d2 phi/dt2`` of the tip, the rods held (index 1: ``a = f + G^T lam``, ``G a + dG v = 0``)."""
    g = rods(q)
    u1, w1, u2, w2 = v
    dgv = np.array([2 * (u1 * u1 + w1 * w1), 2 * ((u2 - u1) ** 2 + (w2 - w1) ** 2)])
    f = np.array([0.0, -G, 0.0, -G])
    lam = np.linalg.solve(g @ g.T, -(g @ f + dgv))
    return float((f + g.T @ lam)[3])


def stopped(q, v, rows) -> np.ndarray:
    """``v`` with the rods' rates and those of ``rows`` made 0 at the least kinetic energy (plastic)."""
    g = np.vstack([rods(q), rows])
    return np.asarray(v) - g.T @ np.linalg.solve(g @ g.T, g @ v)


def _landing(backend: str, landing: str):
    q0, v0 = bobs(*LANDINGS[landing])
    return simulator(backend).simulate(q0=q0, v0=v0, h=0.005, t_end=1.5, params={"mu": 0.5}, progress=False)


@pytest.mark.parametrize("backend", BACKENDS)
@pytest.mark.parametrize("landing", LANDINGS)
def test_a_landing_while_held_not_pressed_coming_in_is_one_plastic_impact(backend, landing):
    res = _landing(backend, landing)
    (imp,) = res.impacts
    assert imp.kind == "plastic" and imp.contact == "tip" and imp.impulse > 1.0
    assert res.stats["impacts_grazing"] == 0 and res.stats["restitution_reduced"] == 0
    # the incoming velocity (the last grid step's) pulls the tip up; stopped, gravity presses it in
    k = imp.step
    v_in = (res.q[k] - res.q[k - 1]) / 0.005
    assert tip_accel(imp.q, v_in) > 1.0
    tip_normal, tip_tangent = [0, 0, 0, 1.0], [0, 0, 1.0, 0]
    frictionless = stopped(imp.q, v_in, [tip_normal])
    assert (tip_accel(imp.q, frictionless) < -1.0) == (landing == "pulled up")
    assert tip_accel(imp.q, stopped(imp.q, v_in, [tip_normal, tip_tangent])) < -1.0
    # held from the landing on, no lift-off; it sticks where it landed and rests there
    after = res.t > imp.t + 0.01
    assert res.active[after, 0].all() and not res.liftoffs
    assert np.abs(res.q[after] - res.q[-1]).max() <= 1e-12
    x1, y1, x2, y2 = res.q[-1]
    assert abs(y2 - FLOOR) <= 1e-12 and abs(x1 * x1 + y1 * y1 - 1) <= 1e-12
    # statics: gravity balanced by the rods' tensions and the tip's normal force and friction
    a = np.column_stack([rods(res.q[-1]).T, [0, 0, 0, 1.0], [0, 0, 1.0, 0]])
    *_, normal, friction = np.linalg.solve(a, [0.0, G, 0.0, G])
    assert normal > 0.0 and abs(res.contact_force[-1, 0] - normal) <= 1e-9 * normal
    assert abs(friction) < 0.5 * normal


def _landing_end(backend: str, start, mu: float) -> np.ndarray:
    q0, v0 = bobs(*start)
    res = simulator(backend).simulate(q0=q0, v0=v0, h=0.005, t_end=1.5, params={"mu": mu}, progress=False)
    assert len(res.impacts) == 1
    return np.concatenate([res.q[-1], res.p[-1]])


@pytest.mark.parametrize("backend", BACKENDS)
@pytest.mark.parametrize("landing", LANDINGS)
def test_the_tangent_goes_through_the_landing_while_held(backend, landing):
    """Against central differences in the start's angles and rates (a start on the rods moves along them: the
    tangent times the bobs' derivative) and in ``mu``."""
    start = np.array(LANDINGS[landing])
    q0, v0 = bobs(*start)
    res = simulator(backend).simulate(
        q0=q0, v0=v0, h=0.005, t_end=1.5, params={"mu": 0.5}, progress=False, sensitivities=True
    )
    assert not res.sensitivity_breaks and np.isfinite(res.sensitivity[-1]).all()
    eps, tangent = 1e-6, res.sensitivity[-1]
    for i in range(4):
        d = np.eye(4)[i] * eps
        central = (_landing_end(backend, start + d, 0.5) - _landing_end(backend, start - d, 0.5)) / (2 * eps)
        moved = (np.concatenate(bobs(*(start + d))) - np.concatenate(bobs(*(start - d)))) / (2 * eps)
        assert np.abs(central - tangent[:, :8] @ moved).max() <= 1e-6 * (1.0 + np.abs(central).max()), i
    central = (_landing_end(backend, start, 0.5 + eps) - _landing_end(backend, start, 0.5 - eps)) / (2 * eps)
    mu = tangent[:, list(res.sensitivity_names).index("mu")]
    assert np.abs(central - mu).max() <= 1e-6 * (1.0 + np.abs(central).max())


# the tip lands (e = 0), is held, lifts off where its force vanishes, hops 1.7e-5 m and lands again (mu = 0)
HOP = (
    [0.07420917759518242, -0.9972426976221218, 0.38045397076295834, -0.045289901178082737],
    [0.6590519224949751, 0.0490429273410516, 3.1401402641590623, -0.7491273063744863],
)


def _accel(y, floor: bool):
    """The bobs' accelerations and the multipliers (the rods', then the floor's if ``floor``), index 1."""
    q, v = y[:4], y[4:]
    g = rods(q)
    u1, w1, u2, w2 = v
    dgv = [2 * (u1 * u1 + w1 * w1), 2 * ((u2 - u1) ** 2 + (w2 - w1) ** 2)]
    if floor:
        g, dgv = np.vstack([g, [0, 0, 0, 1.0]]), [*dgv, 0.0]
    f = np.array([0.0, -G, 0.0, -G])
    lam = np.linalg.solve(g @ g.T, -(g @ f + np.array(dgv)))
    return f + g.T @ lam, lam


@cache
def hop_reference() -> tuple[float, float, float]:
    """scipy: the landing, the lift-off (the floor's multiplier reaching 0) and the hop's landing times."""
    kw = {"method": "DOP853", "rtol": 1e-12, "atol": 1e-13}
    land = lambda t, y: y[3] - FLOOR  # noqa: E731
    lift = lambda t, y: _accel(y, True)[1][2]  # noqa: E731
    land.terminal = lift.terminal = True
    land.direction = lift.direction = -1
    fall = solve_ivp(
        lambda t, y: [*y[4:], *_accel(y, False)[0]], (0, 2), [*HOP[0], *HOP[1]], events=land, **kw
    )
    t1, y1 = fall.t_events[0][0], fall.y_events[0][0]
    v1 = stopped(y1[:4], y1[4:], [[0, 0, 0, 1.0]])
    held = solve_ivp(lambda t, y: [*y[4:], *_accel(y, True)[0]], (t1, 2), [*y1[:4], *v1], events=lift, **kw)
    t2, y2 = held.t_events[0][0], held.y_events[0][0]
    hop = solve_ivp(lambda t, y: [*y[4:], *_accel(y, False)[0]], (t2 + 1e-9, 2), y2, events=land, **kw)
    return float(t1), float(t2), float(hop.t_events[0][0])


@pytest.mark.parametrize("backend", BACKENDS)
def test_a_lift_off_the_map_sinks_after_is_held_on_with_no_impact(backend):
    t_land, t_lift, t_hop = hop_reference()
    assert 0.04 < t_hop - t_lift < 0.06
    errors, hops = [], []
    for h in (0.005, 0.0025):
        res = simulator(backend).simulate(
            q0=HOP[0], v0=HOP[1], h=h, t_end=0.6, params={"mu": 0.0}, progress=False
        )
        assert [i.kind for i in res.impacts] == ["plastic", "plastic"] and min(
            i.impulse for i in res.impacts
        ) > 1e-3
        assert [c for _, c in res.liftoffs] == ["tip"]
        assert res.q[:, 3].min() - FLOOR >= -1e-12
        assert abs(res.impacts[0].t - t_land) <= h * h
        errors.append(abs(res.liftoffs[0][0] - t_lift))
        assert errors[-1] <= 11.0 * h * h, (h, errors[-1])
        hops.append(abs(res.impacts[1].t - t_hop))
        assert hops[-1] <= 70.0 * h * h, (h, hops[-1])
    assert errors[0] / errors[1] > 3.8 and hops[0] / hops[1] > 3.8
    # the hold is a move the tangent has no derivative of: the step breaks there, on both backends alike
    res = simulator(backend).simulate(
        q0=HOP[0], v0=HOP[1], h=0.005, t_end=0.6, params={"mu": 0.0}, progress=False, sensitivities=True
    )
    step = int((res.liftoffs[0][0] - res.t[0]) // 0.005)
    assert res.sensitivity_breaks == [(step, "a lift-off met again moving away")]


# frictionless drops (e = 0) whose tip cycled between lift-off and landing at one instant on one backend
CYCLING = {
    "C's": (
        [-0.8751118755794097, -0.48392066004654904, -0.3235998659407694, 0.3502462916030283],
        [-0.8663208048232616, 1.566636200838011, -2.532951774975987, 2.6685343207014993],
    ),
    "CasADi's": (
        [-0.5677331285827147, -0.8232126667573105, -1.4193220425284543, -1.3474228551786307],
        [-1.597710796549552, 1.10187000968836, -1.8488623447580006, 1.5098702334511325],
    ),
}


@pytest.mark.parametrize("backend", BACKENDS)
@pytest.mark.parametrize("drop", CYCLING)
def test_a_frictionless_cycle_at_one_instant_is_no_painleve_jam(backend, drop):
    with warnings.catch_warnings():
        warnings.simplefilter("error", RuntimeWarning)  # no warning of Painleve's inconsistency
        res = simulator(backend).simulate(
            q0=CYCLING[drop][0], v0=CYCLING[drop][1], h=0.005, t_end=5.0, params={"mu": 0.0}, progress=False
        )
    assert res.stats["jams"] == 0 and res.liftoffs
    assert res.q[:, 3].min() - FLOOR >= -1e-12
