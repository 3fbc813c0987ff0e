"""A rod resting with both ends in a rough circular bowl, tilted: it stands up to a limiting tilt and slides
past it (MATH.md *Friction*: sticking within the cone in sustained contact; the stick split of two dependent
stick rows on curved rows, ``FrictionModes._stick_split``, C ``stick_split``).

A uniform rod (half length ``a = 0.6``, unit mass, ``I = m a^2 / 3``) with both ends on the circle ``|q| = R =
1`` (contacts ``R - |end| >= 0``, Coulomb friction ``mu`` along the arc, ``R atan2(x, -y)``). Turned about the
bowl's centre by ``theta`` from level, its centre sits ``d = sqrt(R^2 - a^2)`` from the centre and its ends at
``theta -+ phi`` (``sin phi = a / R``). Both normal forces pass through the centre, so the friction forces
alone balance gravity's moment about it: ``R (F_1 + F_2) = m g d sin theta``; with the force balance, the
limit ``F_i = mu N_i`` at both ends gives the limiting tilt (solved here with ``brentq``): 0.1559, 0.4586,
0.8659 at ``mu`` = 0.1, 0.3, 0.6. Both ends held, the two stick rows and two normal rows on three coordinates
are dependent: one stick row rides on the other, and the owner's check is their best split.

At rest the forces are statically indeterminate: the friction forces' sum is fixed, not their share. vcigen
takes the best split, both ends equally far inside their cones, ``F_i = mu N_i - m`` (``m`` the common
margin), which with the force and moment balances is a linear system in ``N_1, N_2, m``
(:func:`equal_margins`). The lift-off test and the forces reported read that split
(``FrictionModes._pressed``): before, they read the held stick row's, all the friction on one end, and at
``mu = 0.6`` that end's normal force came out -0.51, a spurious lift-off and landing as the rod stopped.
"""

from __future__ import annotations

import math
import warnings
from functools import cache

import numpy as np
import pytest
import sympy as sp
from hard_scenes import BACKENDS, G
from scipy.optimize import brentq

import vcigen

R, HALF = 1.0, 0.6
DIST, PHI = math.sqrt(R * R - HALF * HALF), math.asin(HALF / R)


def limit(mu: float) -> float:
    """The tilt at which both ends are at the edge of their cones, about to slide down."""

    def moment(th: float) -> float:
        ends = (th - PHI, th + PHI)
        rows = [
            [-math.sin(a) + mu * math.cos(a) for a in ends],
            [math.cos(a) + mu * math.sin(a) for a in ends],
        ]
        normal = np.linalg.solve(np.array(rows), [0.0, G])
        return R * mu * float(normal.sum()) - G * DIST * math.sin(th)

    return brentq(moment, 1e-6, 1.2, xtol=1e-15)


def equal_margins(mu: float, th: float) -> np.ndarray:
    """``(N_1, N_2, m)`` of the rod at rest at tilt ``th``, both ends a margin ``m`` inside their cones."""
    ends = (th - PHI, th + PHI)
    rows = [
        [-math.sin(a) + mu * math.cos(a) for a in ends] + [-sum(math.cos(a) for a in ends)],
        [math.cos(a) + mu * math.sin(a) for a in ends] + [-sum(math.sin(a) for a in ends)],
        [mu, mu, -2.0],
    ]
    return np.linalg.solve(np.array(rows), [0.0, G, G * DIST * math.sin(th) / R])


@cache
def simulator(backend: str) -> vcigen.Simulator:
    x, y, th, xd, yd, thd = sp.symbols("x y th xd yd thd")
    mu = sp.Symbol("mu")
    ends = [(x + s * HALF * sp.cos(th), y + s * HALF * sp.sin(th)) for s in (-1, 1)]
    model = vcigen.Model(
        name="rod_in_bowl",
        q=[x, y, th],
        qdot=[xd, yd, thd],
        lagrangian=(xd**2 + yd**2) / 2 + HALF**2 / 6 * thd**2 - G * y,
        contacts={f"e{i}": R - sp.sqrt(ex**2 + ey**2) for i, (ex, ey) in enumerate(ends)},
        restitution={"e0": 0.0, "e1": 0.0},
        friction={f"e{i}": (mu, R * sp.atan2(ex, -ey)) for i, (ex, ey) in enumerate(ends)},
        params={mu: 0.3},
    )
    return vcigen.build(model, backend=backend)


def run(backend: str, mu: float, tilt: float) -> vcigen.Result:
    start = [DIST * math.sin(tilt), -DIST * math.cos(tilt), tilt]
    return simulator(backend).simulate(start, [0.0] * 3, 0.01, t_end=1.0, params={"mu": mu})


@pytest.mark.parametrize("backend", BACKENDS)
@pytest.mark.parametrize("mu", [0.1, 0.3, 0.6])
def test_a_rod_in_a_rough_bowl_stands_below_its_limiting_tilt_and_slides_above(backend: str, mu: float):
    """2e-4 rad below the limit it stands for a second with both ends held (not a digit moves); 2e-4 above
    it slides down and comes to rest again below the limit (by about the same 2e-4), both ends held at the
    start and the end, with no lift-off and no impact (before stop 48, at mu = 0.6 one end lifted off as
    the rod stopped and landed 3.4e-12 s later, on one backend or the other as round-off chose which stick
    row held). Started 1e-2 and 5e-2 above, it stops without one too."""
    th = limit(mu)
    below = run(backend, mu, th - 2e-4)
    assert below.active.all() and not below.impacts and np.abs(below.q - below.q[0]).max() == 0.0
    for past in (2e-4, 1e-2, 5e-2):
        above = run(backend, mu, th + past)
        assert above.active[0].all() and above.active[-1].all()
        assert not above.liftoffs and not above.impacts, (past, above.liftoffs)
        assert np.abs(above.v[-1]).max() < 1e-12 and th - 1.1 * past < above.q[-1, 2] < th


@pytest.mark.parametrize("backend", BACKENDS)
@pytest.mark.parametrize("mu", [0.1, 0.3, 0.6])
def test_a_resting_rod_reports_the_split_with_both_ends_equally_inside_their_cones(backend: str, mu: float):
    """At rest, below the limit from the start or stopped after sliding (whichever end's stick row holds,
    as round-off chose), both normal forces are the closed form's equal-margin split to 1e-11, and both
    are positive. Before stop 48 they were the held stick row's share: 8.10 and 5.50 against the split's
    7.09 and 4.49 (mu = 0.3), or 3.97 and -0.51 (mu = 0.6)."""
    th = limit(mu)
    for start in (th - 2e-4, th - 5e-2, th + 2e-4, th + 5e-2):
        res = run(backend, mu, start)
        assert np.abs(res.v[-1]).max() < 1e-12
        split = equal_margins(mu, float(res.q[-1, 2]))
        assert split[2] > 0.0 and (split[:2] > 0.0).all()
        np.testing.assert_allclose(res.contact_force[-1], split[:2], rtol=0, atol=1e-11)


@cache
def lifted(backend: str, end: int = 1) -> vcigen.Simulator:
    """The rod with a vertical force ``k t`` on its end ``e1`` (upper at a positive tilt) or ``e0``."""
    x, y, th, xd, yd, thd, t = sp.symbols("x y th xd yd thd t")
    mu, k = sp.symbols("mu k")
    ends = [(x + s * HALF * sp.cos(th), y + s * HALF * sp.sin(th)) for s in (-1, 1)]
    model = vcigen.Model(
        name=f"rod_lifted_in_bowl_{end}",
        q=[x, y, th],
        qdot=[xd, yd, thd],
        lagrangian=(xd**2 + yd**2) / 2 + HALF**2 / 6 * thd**2 - G * y,
        contacts={f"e{i}": R - sp.sqrt(ex**2 + ey**2) for i, (ex, ey) in enumerate(ends)},
        restitution={"e0": 0.0, "e1": 0.0},
        friction={f"e{i}": (mu, R * sp.atan2(ex, -ey)) for i, (ex, ey) in enumerate(ends)},
        forces=[0, k * t, (2 * end - 1) * k * t * HALF * sp.cos(th)],
        time=t,
        params={mu: 1.0, k: 10.0},
    )
    return vcigen.build(model, backend=backend)


def lift(
    backend: str, end: int, tilt: float, mu: float, k: float = 10.0, sens: bool = False
) -> vcigen.Result:
    start = [DIST * math.sin(tilt), -DIST * math.cos(tilt), tilt]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        sim = lifted(backend, end)
        return sim.simulate(start, [0.0] * 3, 0.01, t_end=0.6, params={"mu": mu, "k": k}, sensitivities=sens)


@pytest.mark.parametrize("backend", BACKENDS)
@pytest.mark.parametrize("end, tilt, mu", [(1, 0.2, 1.0), (1, 0.2, 2.0), (0, -0.2, 0.6), (0, -0.2, 1.0)])
def test_a_rod_lifted_by_its_upper_end_leaves_the_bowl_there_at_half_its_weight(backend, end, tilt, mu):
    """Standing at a tilt of 0.2 (both ends sticking, one stick row riding on the other's), lifted at its
    upper end by ``F = k t``: the upper end's normal force vanishes where the moments about the lower end
    balance, ``F = m g / 2`` (the centre halfway between the ends, horizontally), at ``t* = m g / (2 k)``
    (below ``mu = cot phi = 4/3``; above it friction at the upper end can also wedge it: at ``mu = 2``,
    lifted at the contact that holds the stick row, it stays, docs/limits.md). The rod does not move before
    (1e-15), its normal forces stay below ``10 m g`` (at ``mu = 2`` friction jams, the best split's margin
    rises without bound, and before stop 48's ``line_turns`` they were reported as 8.6e19), the upper end
    lifts off at ``t*`` to 1e-12 and the lower one stays held. Lifted at the riding contact (``e1``) its
    split's share of the friction is 0 there and the tangent is carried across the lift-off (test below);
    lifted at the owner (``e0``), the lift-off is located on the best split (``FrictionModes._pressed``),
    which the tangent does not carry: that step breaks, with "lift-off while a stick rides" among its
    reasons (or a friction switch's, where round-off cycled the riding row's stick at that instant)."""
    res = lift(backend, end, tilt, mu, sens=True)
    t_star = G / 20.0
    assert [name for _, name in res.liftoffs] == [f"e{end}"] and abs(res.liftoffs[0][0] - t_star) < 1e-12
    before = res.t < t_star
    assert res.active[before].all() and np.abs(res.q[before] - res.q[0]).max() < 1e-15
    assert np.abs(res.contact_force).max() < 10.0 * G
    assert res.active[-1, 1 - end] and not res.active[-1, end]
    step = int(t_star / 0.01)
    if end == 0:  # where round-off slid and stuck the riding row at that instant first (sticks_kept:
        # CasADi on an Intel Xeon, stop 53; C there and both on an AMD EPYC take the lift-off alone), the
        # switch breaks it
        reasons = {why for k, why in res.sensitivity_breaks if k == step}
        switched = res.stats["sticks_kept"] > 0 and "friction switch in a held step" in reasons
        assert "lift-off while a stick rides" in reasons or switched
    else:
        assert res.sensitivity_breaks == [] and np.isfinite(res.sensitivity).all()


@pytest.mark.parametrize(("end", "tilt"), [(1, 0.2), (0, -0.2)])
def test_a_rod_lifted_sliding_leaves_with_no_impact_after_its_lift_off(end, tilt):
    """At ``mu = 0.3`` the upper end slides before it leaves. After the lift-off the map sank it by its error
    (the exact end rises as the cube of the time since) and the crossings it met moving away were logged as
    impacts of impulse 0 (one in C, three on CasADi, till stop 50; docs/limits.md). Now none: one lift-off, at
    the same time on both backends (1e-12), no impact, the runs within 1e-7 (4.2e-8), never below the bowl."""
    a, b = (lift(backend, end, tilt, 0.3) for backend in ("c", "casadi"))
    for res in (a, b):
        assert not res.impacts and [name for _, name in res.liftoffs] == [f"e{end}"]
    assert abs(a.liftoffs[0][0] - b.liftoffs[0][0]) < 1e-12 and np.abs(a.q - b.q).max() < 1e-7
    ends = [
        (a.q[:, 0] + s * HALF * np.cos(a.q[:, 2]), a.q[:, 1] + s * HALF * np.sin(a.q[:, 2])) for s in (-1, 1)
    ]
    assert min(float((R - np.hypot(ex, ey)).min()) for ex, ey in ends) > -1e-9


@pytest.mark.parametrize("backend", BACKENDS)
def test_the_tangent_across_a_riding_contacts_lift_off_matches_central_differences(backend: str):
    """The rider lifted (``e1``, ``mu = 1``): ``d(q, p)/d(k, tilt)`` at every grid point against central
    differences of whole runs (1e-6: measured 1.9e-9), the lift-off's time moving with them."""
    res = lift(backend, 1, 0.2, 1.0, sens=True)
    names = [str(s) for s in lifted(backend, 1).model.defaults]
    eps = 1e-6

    def z(k, tilt):
        return np.array(
            [DIST * math.sin(tilt), -DIST * math.cos(tilt), tilt, 0, 0, 0]
            + [1.0 if n == "mu" else k for n in names]
        )

    for dk, dt in ((1.0, 0.0), (0.0, 1.0)):
        ends = [lift(backend, 1, 0.2 + sign * eps * dt, 1.0, 10.0 + sign * eps * dk) for sign in (1.0, -1.0)]
        assert all(len(r.liftoffs) == 1 for r in ends)
        fd = (np.hstack([ends[0].q, ends[0].p]) - np.hstack([ends[1].q, ends[1].p])) / (2 * eps)
        dz = (z(10.0 + 1e-4 * dk, 0.2 + 1e-4 * dt) - z(10.0 - 1e-4 * dk, 0.2 - 1e-4 * dt)) / 2e-4
        exact = res.sensitivity @ dz
        assert np.abs(exact - fd).max() < 1e-6 * np.abs(exact).max()
