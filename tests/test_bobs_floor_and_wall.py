"""A chain of three bobs in maximal coordinates (its rods bilateral constraints, held throughout) whose middle
bob lands on a floor while its tip touches a wall, frictionless, ``e = 0`` (MATH.md *Sustained contact*: an
impact while rows are held).

Unit masses, rods of 1, 1 and 0.6, the pivot at the origin, the floor ``y = FLOOR`` under every bob, the
wall ``x = WALL`` before the tip. The start is drop 2312 of a random campaign (its state at t = 0.6): the tip
hits the wall, then the middle bob the floor, which sets the tip moving into the wall again; met alone, each
``e = 0`` impact stopped its row and left the other moving in (normal speeds 0.55, 0.22, 0.045, 0.0095 ...),
a lift-off of each between, and from ``LIFT_CYCLES`` pulls both were held on to the step's end at forces of
-17.7 and -16.8. The limit of those impacts is one plastic impact on both rows, after which both pull and
leave; rows met at this instant that touch at rest now join the impulse law (``HeldImpacts._joined``).

Checked against an independent reference: scipy (DOP853, rtol 1e-12) integrates the rods' index-1 equations
between impacts located as events; at each impact the impulses are the complementarity problem of every row
that touches (``|psi| <= 1e-9``) with targets 0 (``e = 0``), solved by enumeration; a row left at a normal
speed of 0 must be pulled off (the reference holds no row; asserted).

A second start (drop 2476 of the same campaign, at t = 0.5): the tip lands on the floor pressed in by the
incoming velocity; once stopped, the rods pull it up (its held force -9.28). The impact is plastic and the tip
lifts off at its instant (MATH.md *Entry*); read at the end of the rest of the step alone (0.98 h later),
where its force pushes again, the tip was held through the step at a mean force of -4.36
(``SustainedSteps._start_forces``: after an impact while held, the held rows' forces are read at the
segment's start too).
"""

from __future__ import annotations

import itertools
from functools import cache

import numpy as np
import pytest
import sympy as sp
from hard_scenes import BACKENDS, G
from scipy.integrate import solve_ivp

import vcigen

FLOOR, WALL = -1.4, 1.6
LENGTHS = (1.0, 1.0, 0.6)
X1, Y1, X2, Y2, X3, Y3 = sp.symbols("x1 y1 x2 y2 x3 y3")
U1, V1, U2, V2, U3, V3 = sp.symbols("u1 v1 u2 v2 u3 v3")
MU, E = sp.symbols("mu e")
# drop 2312 (seed 7) of the random campaign, at t = 0.6 of its run: on the rods, moving along them
Q0 = [0.2859413249505944, -0.9582471281905824, 1.1835845241337797, -1.3989700422308853]
Q0 += [1.5975178793645424, -0.9646208999186169]
V0 = [-2.480717345039856, -0.740247044421655, -1.9866713703899352, 0.2660019957355256]
V0 += [3.5001233999728534, -4.96289602088828]
# drop 2476 at t = 0.5: the tip lands pressed in, pulled once stopped
Q_TIP = [-0.4362567892760264, -0.8998222123345104, 0.4969617512107751, -1.2591314881564466]
Q_TIP += [1.0864140894777277, -1.371140152605328]
V_TIP = [0.30270211776366546, -0.14675771746067803, -3.1060167608275706, -9.000076768386533]
V_TIP += [-2.475201742453778, -5.6803747665468345]
STARTS = {"bob and wall": (Q0, V0, 0.05), "tip pulled once stopped": (Q_TIP, V_TIP, 0.01)}
STEPS = (0.005, 0.0025)


@cache
def simulator(backend: str) -> vcigen.Simulator:
    ends = [(0, 0, X1, Y1), (X1, Y1, X2, Y2), (X2, Y2, X3, Y3)]
    model = vcigen.Model(
        name="bobs_wall",
        q=[X1, Y1, X2, Y2, X3, Y3],
        qdot=[U1, V1, U2, V2, U3, V3],
        lagrangian=(U1**2 + V1**2 + U2**2 + V2**2 + U3**2 + V3**2) / 2 - G * (Y1 + Y2 + Y3),
        contacts={"tip": Y3 - FLOOR, "mid": Y2 - FLOOR, "elbow": Y1 - FLOOR, "wall": WALL - X3},
        constraints={
            f"r{i + 1}": (b - a) ** 2 + (d - c) ** 2 - length**2
            for i, ((a, c, b, d), length) in enumerate(zip(ends, LENGTHS))
        },
        restitution={"tip": E, "mid": E, "elbow": E, "wall": E},
        friction={"tip": (MU, X3), "mid": (MU, X2), "elbow": (MU, X1), "wall": (MU, Y3)},
        params={MU: 0.0, E: 0.0},
    )
    return vcigen.build(model, backend=backend)


def rod_rows(q) -> np.ndarray:
    """The rods' gradients (rows) at ``q``."""
    x = np.concatenate([[0.0, 0.0], q])
    out = np.zeros((3, 6))
    for i in range(3):
        d = x[2 * i + 2 : 2 * i + 4] - x[2 * i : 2 * i + 2]
        out[i, 2 * i : 2 * i + 2] = 2 * d
        if i:
            out[i, 2 * i - 2 : 2 * i] = -2 * d
    return out


def rod_curv(v) -> np.ndarray:
    """``d/dt(grad c) . v`` of the rods: ``2 |v_b - v_a|^2``."""
    w = np.concatenate([[0.0, 0.0], v])
    rel = [w[2 * i + 2 : 2 * i + 4] - w[2 * i : 2 * i + 2] for i in range(3)]
    return np.array([2 * float(d @ d) for d in rel])


def contact_psi(q) -> np.ndarray:
    return np.array([q[5] - FLOOR, q[3] - FLOOR, q[1] - FLOOR, WALL - q[4]])


CONTACT_GRAD = np.zeros((4, 6))
CONTACT_GRAD[0, 5] = CONTACT_GRAD[1, 3] = CONTACT_GRAD[2, 1] = 1.0
CONTACT_GRAD[3, 4] = -1.0
GRAVITY = np.array([0.0, -G] * 3)


def accel(q, v, held=()) -> tuple[np.ndarray, np.ndarray]:
    """The index-1 equations (unit masses) with the rods and the contact rows ``held``: ``(a, forces of the
    held rows)``."""
    g = np.vstack([rod_rows(q), CONTACT_GRAD[list(held)]])
    rhs = -np.concatenate([rod_curv(v), np.zeros(len(held))])
    lam = np.linalg.solve(g @ g.T, rhs - g @ GRAVITY)
    return GRAVITY + g.T @ lam, lam[3:]


def plastic_impact(q, v) -> tuple[np.ndarray, list[int], np.ndarray]:
    """The ``e = 0`` impact on every contact row that touches: the velocity after, the rows left at a normal
    speed of 0 (tight) and their impulses, from the complementarity problem by enumeration (largest tight set
    first)."""
    touching = [j for j in range(4) if abs(contact_psi(q)[j]) <= 1e-9]
    rods = rod_rows(q)
    for n in range(len(touching), -1, -1):
        for tight in itertools.combinations(touching, n):
            g = np.vstack([rods, CONTACT_GRAD[list(tight)]])
            lam = np.linalg.solve(g @ g.T, -g @ v)
            w = v + g.T @ lam
            rates = CONTACT_GRAD[touching] @ w
            if np.all(lam[3:] >= -1e-12) and np.all(rates >= -1e-12):
                return w, list(tight), lam[3:]
    raise AssertionError("no plastic impact")


@cache
def reference(start: str) -> tuple[np.ndarray, list[tuple[float, str]]]:
    """``q`` at the end of ``STARTS[start]`` and the impacts ``(t, contacts with an impulse)`` of the
    event-driven reference."""
    q0, v0, t_end = STARTS[start]
    names = ["tip", "mid", "elbow", "wall"]
    events = []
    for j in range(4):
        ev = lambda t, y, j=j: contact_psi(y[:6])[j]  # noqa: E731
        ev.terminal, ev.direction = True, -1
        events.append(ev)
    t, y, impacts = 0.0, np.array(q0 + v0), []
    while True:
        sol = solve_ivp(
            lambda t, y: [*y[6:], *accel(y[:6], y[6:])[0]],
            (t, t_end),
            y,
            method="DOP853",
            rtol=1e-12,
            atol=1e-13,
            events=events,
        )
        if sol.status == 0:
            return sol.y[:6, -1], impacts
        t, y = float(sol.t[-1]), sol.y[:, -1].copy()
        w, tight, lam = plastic_impact(y[:6], y[6:])
        hit = [names[j] for j, x in zip(tight, lam) if x > 1e-12]
        impacts.append((t, " ".join(hit)))
        y[6:] = w
        if tight:  # the reference holds no row: each left at 0 must be pulled off (its held force < 0)
            forces = accel(y[:6], w, tight)[1]
            assert np.all(forces < 0.0), (t, tight, forces)


def test_the_reference_meets_both_contacts_at_once():
    """The premise: the reference's third impact is on the middle bob and the wall together (the limit of the
    impacts met alone), both left at 0 and pulled off (``reference`` asserts it); the tip's start: one
    impact, the tip left at 0 and pulled off."""
    assert [c for _, c in reference("bob and wall")[1]] == ["wall", "mid", "mid wall"]
    assert [c for _, c in reference("tip pulled once stopped")[1]] == ["tip"]


@pytest.mark.parametrize("backend", BACKENDS)
def test_both_leave_pulled_off_not_held_on(backend):
    """After the impacts at one instant both rows lift off there: no row held on (``lifts_kept``), no force
    below 0 (the hold-on pulled at -17.7 and -16.8), the lift-off at the reference's impact on both."""
    q0, v0, t_end = STARTS["bob and wall"]
    t_both = reference("bob and wall")[1][2][0]
    for h in STEPS:
        res = simulator(backend).simulate(q0=q0, v0=v0, h=h, t_end=t_end)
        assert res.stats["lifts_kept"] == 0
        assert float(res.contact_force.min()) >= 0.0
        lifts = {name: t for t, name in res.liftoffs}
        assert sorted(lifts) == ["mid", "wall"] and len(res.liftoffs) == 2
        for name in ("mid", "wall"):
            assert abs(lifts[name] - t_both) <= 2.0 * h**2
        assert all(im.t <= lifts["mid"] + 1e-12 for im in res.impacts)


@pytest.mark.parametrize("backend", BACKENDS)
def test_a_landing_pulled_once_stopped_lifts_off_at_once(backend):
    """The tip's landing is one plastic impact and its lift-off at the same instant, at the reference's
    impact to O(h^2); no force below 0 (held through the step: a mean of -4.36)."""
    q0, v0, t_end = STARTS["tip pulled once stopped"]
    t_ref = reference("tip pulled once stopped")[1][0][0]
    for h in STEPS:
        res = simulator(backend).simulate(q0=q0, v0=v0, h=h, t_end=t_end)
        assert [(im.contact, im.kind) for im in res.impacts] == [("tip", "plastic")]
        assert [name for _, name in res.liftoffs] == ["tip"]
        assert res.liftoffs[0][0] == res.impacts[0].t
        assert abs(res.impacts[0].t - t_ref) <= 0.1 * h**2
        assert float(res.contact_force.min()) >= 0.0


@pytest.mark.parametrize("start", list(STARTS))
@pytest.mark.parametrize("backend", BACKENDS)
def test_the_bobs_follow_the_reference_at_second_order(backend, start):
    """``q`` at the end against the reference: within ``3 h^2`` and second order."""
    q0, v0, t_end = STARTS[start]
    q_ref = reference(start)[0]
    errs = []
    for h in STEPS:
        res = simulator(backend).simulate(q0=q0, v0=v0, h=h, t_end=t_end)
        assert abs(res.t[-1] - t_end) <= 1e-12
        errs.append(float(np.abs(res.q[-1] - q_ref).max()))
        assert errs[-1] <= 3.0 * h**2
        below = min(float((res.q[:, j] - FLOOR).min()) for j in (1, 3, 5))
        assert below >= -1e-9 and float((WALL - res.q[:, 4]).min()) >= -1e-9
    assert np.log2(errs[0] / errs[1]) >= 1.8
