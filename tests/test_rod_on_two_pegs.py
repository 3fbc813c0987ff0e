"""A rough rod lying on two pegs (MATH.md *Friction*: two frictional contacts of one body, sliding together,
a lift-off where a normal force vanishes, then sliding on a row curved in configuration space), against
closed forms and scipy.

A uniform rod (half length ``A = 1.5``, unit mass, ``I = A^2 / 3``) lies on two fixed pegs, the upper at
``(0, 0)`` and the lower at ``(1, -0.4)``; the contacts are the pegs' distances to the rod's line, ``(c - P_i)
. nrm >= 0``, with Coulomb friction ``mu`` along the rod, the tangent ``s_i = (c - P_i) . e`` (``e`` the
rod's direction, ``nrm`` its normal, ``c`` its centre). Friction acts along the rod's line, through its
centre, so the moments balance with the normal forces alone: ``N_i`` is ``m g cos th`` shared in inverse
proportion to the centre's distances to the pegs.

* ``tan |th| = 0.4 <= mu``: the rod rests; its normal forces are that share exactly.
* ``mu < 0.4``: both contacts slide, the rod translates along its line at ``a = g (sin |th| - mu cos
  |th|)``, and the upper peg's force reaches 0 as the centre passes the lower peg: the lift-off at ``t* =
  sqrt(2 D / a)`` (``D`` the centre's start distance to the lower peg). The discrete trajectory of a constant
  acceleration is exact, so the lift-off time is too, to round-off.
* After it the rod pivots on the lower peg and slides on it: with ``c = P_1 + s e(th)``, ``N = (g cos th +
  2 sd thd) / (1 + s^2 / I)``, ``I thdd = -s N``, ``sdd = s thd^2 - g sin th - mu N sign(sd)``. scipy
  integrates that from the lift-off (rtol 1e-12); vcigen's ``q`` stays within 1.10 h^2 of it (h = 0.01,
  0.005, 0.0025), both backends.
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

A = 1.5
PEGS = ((0.0, 0.0), (1.0, -0.4))
TH0 = math.atan2(PEGS[1][1] - PEGS[0][1], PEGS[1][0] - PEGS[0][0])  # the line through the pegs, going down
SPAN = math.hypot(PEGS[1][0] - PEGS[0][0], PEGS[1][1] - PEGS[0][1])
INERTIA = A * A / 3.0


@cache
def simulator(backend: str) -> vcigen.Simulator:
    x, y, th, xd, yd, thd = sp.symbols("x y th xd yd thd")
    mu = sp.Symbol("mu")
    e, nrm = (sp.cos(th), sp.sin(th)), (-sp.sin(th), sp.cos(th))
    model = vcigen.Model(
        name="rod_on_pegs",
        q=[x, y, th],
        qdot=[xd, yd, thd],
        lagrangian=(xd**2 + yd**2) / 2 + INERTIA / 2 * thd**2 - G * y,
        contacts={f"p{i}": (x - px) * nrm[0] + (y - py) * nrm[1] for i, (px, py) in enumerate(PEGS)},
        restitution={"p0": 0.0, "p1": 0.0},
        friction={f"p{i}": (mu, (x - px) * e[0] + (y - py) * e[1]) for i, (px, py) in enumerate(PEGS)},
        params={mu: 0.1},
    )
    return vcigen.build(model, backend=backend)


def start(frac: float) -> list[float]:
    """The rod on both pegs at rest, its centre ``frac`` of the way from the upper peg to the lower."""
    (x0, y0), (x1, y1) = PEGS
    return [x0 + frac * (x1 - x0), y0 + frac * (y1 - y0), TH0]


def pivot_reference(mu: float, t0: float, sd0: float, times: np.ndarray) -> np.ndarray:
    """``q`` at ``times`` of the rod sliding on the lower peg from the lift-off (``s = 0``, ``sd = sd0``, ``th
    = TH0``, ``thd = 0`` at ``t0``), while it presses and slides down (checked)."""

    def rhs(_t, y):
        s, th, sd, thd = y
        normal = (G * math.cos(th) + 2.0 * sd * thd) / (1.0 + s * s / INERTIA)
        sdd = s * thd * thd - G * math.sin(th) - mu * normal * math.copysign(1.0, sd)
        return [sd, thd, sdd, -s * normal / INERTIA]

    sol = solve_ivp(rhs, (t0, times[-1]), [0.0, TH0, sd0, 0.0], rtol=1e-12, atol=1e-13, dense_output=True)
    s, th, sd, thd = sol.sol(times)
    assert (sd > 0).all() and ((G * np.cos(th) + 2.0 * sd * thd) > 0).all() and (np.abs(s) < A).all()
    return np.column_stack([PEGS[1][0] + s * np.cos(th), PEGS[1][1] + s * np.sin(th), th])


@pytest.mark.parametrize("backend", BACKENDS)
@pytest.mark.parametrize("mu", [0.45, 1.0])
def test_a_rod_on_two_rough_pegs_rests_with_the_statics_normal_forces(backend: str, mu: float):
    """``mu >= tan |th|``: not a digit of ``q`` moves in 0.5 s, and the normal forces are ``m g cos th``
    shared by the lever rule, to 1e-12."""
    for frac in (0.3, 0.5, 0.8):
        res = simulator(backend).simulate(start(frac), [0.0] * 3, 0.01, t_end=0.5, params={"mu": mu})
        assert np.abs(res.q - res.q[0]).max() == 0.0 and not res.liftoffs and not res.impacts
        statics = np.tile(G * math.cos(TH0) * np.array([1.0 - frac, frac]), (len(res.contact_force), 1))
        np.testing.assert_allclose(res.contact_force, statics, rtol=0, atol=1e-12)


@pytest.mark.parametrize("backend", BACKENDS)
def test_a_rod_sliding_on_two_rough_pegs_leaves_the_upper_as_its_centre_passes_the_lower(backend: str):
    """``mu = 0.1``: both contacts slide; the upper peg lifts off at the closed form's ``t*`` (to 1e-12: a
    constant acceleration's trajectory is exact), the rod's centre along its line is ``a t^2 / 2`` at every
    grid point before it (1e-12); after it the rod pivots on the lower peg and slides, within 1.10 h^2 of
    scipy, at order 2, and never lifts off the lower peg or meets the upper one again."""
    mu, frac, t_end = 0.1, 0.3, 1.2
    acc = G * (math.sin(-TH0) - mu * math.cos(TH0))
    t_star = math.sqrt(2.0 * (1.0 - frac) * SPAN / acc)
    errors = []
    for h in (0.01, 0.005, 0.0025):
        res = simulator(backend).simulate(start(frac), [0.0] * 3, h, t_end=t_end, params={"mu": mu})
        assert [name for _, name in res.liftoffs] == ["p0"] and not res.impacts
        assert abs(res.liftoffs[0][0] - t_star) < 1e-12
        before = res.t < t_star
        along = (res.q[before, :2] - start(frac)[:2]) @ [math.cos(TH0), math.sin(TH0)]
        np.testing.assert_allclose(along, acc * res.t[before] ** 2 / 2, rtol=0, atol=1e-12)
        after = res.t > t_star
        assert res.active[after, 1].all() and not res.active[after, 0].any()
        ref = pivot_reference(mu, t_star, acc * t_star, res.t[after])
        errors.append(float(np.abs(res.q[after] - ref).max()))
        assert errors[-1] < 1.10 * h * h, (h, errors[-1] / h**2)
    assert math.log2(errors[0] / errors[1]) > 1.9 and math.log2(errors[1] / errors[2]) > 1.9
