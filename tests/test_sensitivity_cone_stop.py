"""The tangent through a slipping isotropic cone that stops and rolls on (stop 28).

The ball of ``tests/test_friction_3d.py`` (``m = 1, I = 0.4, r = 1``, ``mu = 0.3``, two tangents ``x - r
ay``, ``y + r ax``) resting on the floor, sliding at ``(0, 1.5)`` without spin, pushed along ``x`` by a
constant force ``m push`` (``push = 2``, a floor tilted in ``x``): its sliding ``w`` shrinks at ``mu g k``
(``k = 1 + m r^2/I``) while the push turns it, until it stops at step 16 and rolls on (``mu g = 2.9 > push
(1 - 1/k)``). The stop is a located event of the cone (``SustainedSteps._cone_stop``: the root of ``-slip .
w`` along the slip frozen over the segment), which the tangent now carries
(``SwitchTangents._cone_stop_root``, C ``sens_cone_stop_root``; before, a break ``"friction switch in a held
step"``): the root's tangent includes the slip's own (the aim moves with the segment's start,
``Tracker._cone_slots``). Without the push the sliding keeps its direction along ``y``: the cone's ``x``
slip is 0 throughout, and its force law's own column (``-N grad t_x dslip_x``) was dropped by the tangent
(``if slip[f]``), an error of 7e-4 after one step in ``v0[x]``: fixed on both backends (``_cone_slots``,
``_dforce``; C ``sens_slipping``). Two pucks, one stopping while the other slips: the stop carried on both
backends (stop 31; C broke there).
"""

from __future__ import annotations

import math
from functools import cache

import numpy as np
import pytest
import sympy as sp
from hard_scenes import BACKENDS
from test_friction_3d import BALL_MU, INERTIA, MASS, RADIUS, G

import vcigen

PUSH = 2.0
Q0, V0 = [0.0, 0.0, RADIUS, 0.0, 0.0], [0.0, 1.5, 0.0, 0.0, 0.0]
NAMES = ("q0[x]", "v0[x]", "v0[y]", "v0[ax]", "v0[ay]", "mu", "push", "m")


def pushed_ball() -> vcigen.Model:
    x, y, z, ax, ay = sp.symbols("x y z ax ay")
    xd, yd, zd, axd, ayd = sp.symbols("xd yd zd axd ayd")
    m, inertia, r, g, mu, e, push = sp.symbols("m I r g mu e push")
    return vcigen.Model(
        name="pushed_ball",
        q=[x, y, z, ax, ay],
        qdot=[xd, yd, zd, axd, ayd],
        lagrangian=m / 2 * (xd**2 + yd**2 + zd**2) + inertia / 2 * (axd**2 + ayd**2) - m * (g * z - push * x),
        contacts={"floor": z - r},
        params={m: MASS, inertia: INERTIA, r: RADIUS, g: G, mu: BALL_MU, e: 0.0, push: PUSH},
        restitution={"floor": e},
        friction={"floor": (mu, (x - r * ay, y + r * ax))},
    )


@cache
def sim(backend: str) -> vcigen.Simulator:
    return vcigen.build(pushed_ball(), backend=backend)


def sliding(p: np.ndarray) -> float:
    return math.hypot(p[0] / MASS - RADIUS * p[4] / INERTIA, p[1] / MASS + RADIUS * p[3] / INERTIA)


def tangent_error(backend: str, push: float, t_end: float, h: float = 0.01) -> tuple[float, vcigen.Result]:
    """The run's tangent at ``t_end`` against central differences of whole runs (eps 1e-5, the stop's time in
    them), relative to the largest entry, over ``NAMES``."""
    kw = {"h": h, "t_end": t_end, "progress": False}
    base = {"mu": BALL_MU, "push": push, "m": MASS}
    res = sim(backend).simulate(Q0, V0, sensitivities=True, params={"push": push}, **kw)

    def end(name: str, e: float) -> np.ndarray:
        q, v, par = list(Q0), list(V0), {"push": push}
        if name in base:
            par[name] = base[name] + e
        else:
            (q if name[0] == "q" else v)[["x", "y", "z", "ax", "ay"].index(name[3:-1])] += e
        r = sim(backend).simulate(q, v, params=par, **kw)
        return np.concatenate([r.q[-1], r.p[-1]])

    worst = 0.0
    for name in NAMES:
        fd = (end(name, 1e-5) - end(name, -1e-5)) / 2e-5
        exact = res.sensitivity[-1, :, res.sensitivity_names.index(name)]
        worst = max(worst, float(np.abs(fd - exact).max() / max(1.0, np.abs(exact).max())))
    return worst, res


@pytest.mark.parametrize("backend", BACKENDS)
def test_the_tangent_through_a_cones_stop_against_central_differences(backend: str) -> None:
    """Pushed: the stop at step 16 carried (no break, rolling at the end, held throughout); the state at
    t = 0.5 against central differences to 1e-7 (1.4e-9 seen; the one-tangent root instead: 1.3e-4; the root
    without the slip's own tangent: 1.3e-5); C's tangent against CasADi's to 1e-12."""
    worst, res = tangent_error(backend, PUSH, 0.5)
    stops = [k for k in range(1, res.p.shape[0]) if sliding(res.p[k]) <= 1e-12 < sliding(res.p[k - 1])]
    print(f"{backend}: pushed ball, stops at step {stops}, tangent vs central differences {worst:.1e}")
    assert res.sensitivity_breaks == [] and not res.impacts and res.active[:, 0].all()
    assert stops == [16] and sliding(res.p[-1]) <= 1e-12
    assert worst <= 1e-7
    if backend == "c":
        ref = tangent_error("casadi", PUSH, 0.5)[1]
        scale = max(1.0, float(np.abs(ref.sensitivity[-1]).max()))
        gap = float(np.abs(res.sensitivity[-1] - ref.sensitivity[-1]).max()) / scale
        print(f"C vs CasADi tangent {gap:.1e}")
        assert gap <= 1e-12


@pytest.mark.parametrize("steps", [15, 16])
@pytest.mark.parametrize("backend", BACKENDS)
def test_a_cones_stop_on_a_grid_point_carries_the_tangent(backend: str, steps: int) -> None:
    """Not pushed, the ball's sliding ``1.5`` shrinks at ``mu g k`` and stops at ``t* = 1.5 / (mu g k)``;
    ``h = t* / steps`` puts the stop on grid point ``steps``, where the sliding is round-off's. The stop is
    located at that step's end (``SustainedSteps._cone_stop``, ``SLIDE_EPS``) and the tangent goes through it
    (``Tracker.rest_end``, C ``sens_ev_rest_end``); before stop 63 both backends broke there, ``"friction
    switch in a held step"``. The state at t = 0.3 against central differences to 1e-7 (2.9e-10 seen)."""
    k = 1.0 + MASS * RADIUS**2 / INERTIA
    t_stop = 1.5 / (BALL_MU * G * k)
    worst, res = tangent_error(backend, 0.0, 0.3, t_stop / steps)
    stops = [j for j in range(1, res.p.shape[0]) if sliding(res.p[j]) <= 1e-12 < sliding(res.p[j - 1])]
    assert res.sensitivity_breaks == [] and np.isfinite(res.sensitivity).all() and stops == [steps]
    assert worst <= 1e-7


@pytest.mark.parametrize("backend", BACKENDS)
def test_a_cone_slipping_along_one_tangent_keeps_the_others_column(backend: str) -> None:
    """Unpushed: sliding along ``y``, the ``x`` slip 0 (its tangent not): one step against central differences
    to 1e-9 (7e-4 before the fix, ``v0[x]``), and through its stop at t = 0.146 to t = 0.3."""
    for t_end in (0.01, 0.3):
        worst, res = tangent_error(backend, 0.0, t_end)
        print(f"{backend}: unpushed ball to t = {t_end}, tangent vs central differences {worst:.1e}")
        assert res.sensitivity_breaks == []
        assert worst <= 1e-9 if t_end == 0.01 else worst <= 1e-7


def two_pucks() -> vcigen.Model:
    """Two unit point masses on the floor ``z = 0``, each with its own isotropic cone (``mu``)."""
    q = sp.symbols("x1 y1 z1 x2 y2 z2")
    qd = sp.symbols("x1d y1d z1d x2d y2d z2d")
    mu = sp.Symbol("mu")
    return vcigen.Model(
        name="two_pucks",
        q=list(q),
        qdot=list(qd),
        lagrangian=sum(v**2 for v in qd) / 2 - G * (q[2] + q[5]),
        contacts={"f1": q[2], "f2": q[5]},
        params={mu: 0.3},
        friction={"f1": (mu, q[:2]), "f2": (mu, q[3:5])},
    )


@pytest.mark.parametrize("backend", BACKENDS)
def test_a_cone_stopping_while_another_slips_carries_the_tangent(backend: str) -> None:
    """Two pucks on the floor sliding at ``|(1, 0.2)|`` and ``|(3, 1)|``: the first stops at ``|w| / (mu
    g) = 0.347`` (step 69) while the second slips on (to 1.07). The stop is carried on both backends, as on
    CasADi before: C's check that no other contact switched with it compared the other cone's slip with
    its mode's flag (1 for a slipping cone, ``<model>_fmode_t.slip``) instead of its aim, and broke at
    every cone's stop while another cone slipped (``"friction switch in a held step"``). The state at t =
    0.6 (the first at rest, the second at ``(1 - 0.6 mu g / |w|) (3, 1)``) against central differences of
    whole runs (eps 1e-6) over ``x, y`` of ``q0`` and ``v0`` of both, to 1e-7 (7e-9 seen)."""
    sim2 = vcigen.build(two_pucks(), backend=backend)
    q0, v0 = np.array([0.0, 0.0, 0.0, 0.0, 1.0, 0.0]), np.array([1.0, 0.2, 0.0, 3.0, 1.0, 0.0])
    kw = {"h": 0.005, "t_end": 0.6, "progress": False}
    res = sim2.simulate(q0, v0, sensitivities=True, **kw)
    assert res.sensitivity_breaks == [] and not res.impacts and res.active[:, :2].all()
    mu_g = 0.3 * G
    w2 = math.hypot(3.0, 1.0)
    assert np.abs(res.v[-1, :3]).max() < 1e-12
    assert np.abs(res.v[-1, 3:5] - (1 - 0.6 * mu_g / w2) * np.array([3.0, 1.0])).max() < 1e-9
    worst = 0.0
    for j in (0, 1, 3, 4, 6, 7, 9, 10):
        d = np.zeros(12)
        d[j] = 1e-6
        ends = [sim2.simulate(q0 + s * d[:6], v0 + s * d[6:], **kw) for s in (1, -1)]
        fd = np.concatenate([ends[0].q[-1] - ends[1].q[-1], ends[0].p[-1] - ends[1].p[-1]]) / 2e-6
        worst = max(worst, float(np.abs(fd - res.sensitivity[-1, :, j]).max()))
    print(f"{backend}: two pucks, tangent vs central differences {worst:.1e}")
    assert worst <= 1e-7


def puck_and_lifter() -> vcigen.Model:
    """:func:`two_pucks` with an upward force ``c x2`` on the second (the potential ``-c x2 z2``): sliding
    along ``x`` it presses the floor less, until it lifts off where ``c x2 = g``."""
    q = sp.symbols("x1 y1 z1 x2 y2 z2")
    qd = sp.symbols("x1d y1d z1d x2d y2d z2d")
    mu, c = sp.symbols("mu c")
    return vcigen.Model(
        name="puck_and_lifter",
        q=list(q),
        qdot=list(qd),
        lagrangian=sum(v**2 for v in qd) / 2 - G * (q[2] + q[5]) + c * q[3] * q[5],
        contacts={"f1": q[2], "f2": q[5]},
        params={mu: 0.3, c: 20.0},
        friction={"f1": (mu, q[:2]), "f2": (mu, q[3:5])},
    )


@pytest.mark.parametrize("backend", BACKENDS)
def test_a_lift_off_while_another_cone_slips_carries_the_tangent(backend: str) -> None:
    """Both pucks slide along ``x`` (at 5 and 3); the second, pressed less as it goes (``N = g - c x2``),
    brakes by ``x2'' = -mu (g - c x2)`` and lifts off where ``c x2 = g``: ``tanh(k t) = k g / (3 c)``, ``k =
    sqrt(mu c)``, t = 0.1732 (step 34). The friction mode changes there only by a contact let go, which the
    tangent carries (``SustainedSteps._no_switch``). C's ``<model>_no_switch`` compared the first cone's slip
    with the snapshot's mode flag (1 for a slipping cone) and broke there (``"friction switch in a held
    step"``), CasADi did not; the snapshot now holds the slips themselves. The lift-off time against the
    closed form to 1e-4 (order 2 in h), no break, and the state at t = 0.3 against central differences of
    whole runs (eps 1e-6, ``x`` of ``q0``, ``x``, ``z`` of ``v0``) to 1e-7 (3.7e-9 seen); ``z`` of ``v0`` by
    the backward difference (1.0e-8 seen; central 7.4e-5 since stop 37: a kink, see the loop)."""
    sim2 = vcigen.build(puck_and_lifter(), backend=backend)
    q0, v0 = np.zeros(6), np.array([5.0, 0.0, 0.0, 3.0, 0.0, 0.0])
    kw = {"h": 0.005, "t_end": 0.3, "progress": False}
    res = sim2.simulate(q0, v0, sensitivities=True, **kw)
    k = math.sqrt(0.3 * 20.0)
    exact = math.atanh(k * G / (3.0 * 20.0)) / k
    assert [j for _, j in res.liftoffs] == ["f2"] and abs(res.liftoffs[0][0] - exact) < 1e-4
    assert res.sensitivity_breaks == [] and not res.impacts
    worst = 0.0
    for j in (0, 3, 6, 9, 11):
        d = np.zeros(12)
        d[j] = 1e-6
        # z of v0 (j = 11) is the normal speed of a puck at rest on its rough floor: the map has a kink there
        # (moving off faster than admissible / h it flies and lands with Coulomb's impulse, stop 37; moving in
        # it takes that impulse at once), and the held start's tangent is the side into the floor's
        sides = (0.0, -1.0) if j == 11 else (1.0, -1.0)
        ends = [sim2.simulate(q0 + s * d[:6], v0 + s * d[6:], **kw) for s in sides]
        fd = np.concatenate([ends[0].q[-1] - ends[1].q[-1], ends[0].p[-1] - ends[1].p[-1]])
        fd = fd / (1e-6 * (sides[0] - sides[1]))
        worst = max(worst, float(np.abs(fd - res.sensitivity[-1, :, j]).max()))
    print(f"{backend}: a lift-off while a cone slips, tangent vs central differences {worst:.1e}")
    assert worst <= 1e-7
