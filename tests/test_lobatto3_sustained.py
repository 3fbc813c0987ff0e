"""Sustained contact and bilateral constraints under the fourth-order rule ``lobatto3``, both backends.

The constrained step holds the internal point ``q_m`` on the active rows too, with its own multipliers
(``vcigen.derive.held_internal_points``: ``D_m L_d + G_m^T Lam_m = 0``, ``psi(q_m) = 0``). References are
independent of vcigen: scipy's DOP853 at rtol 1e-13 on the minimal-coordinate ODE (the pendulum's angle,
the angle on the dome with the lift-off event), the quadrature closed form of the dome's lift-off time,
closed forms of the incline and of the Zeno sequence. C = CasADi on the same scenes.
"""

from __future__ import annotations

import math
from functools import cache

import numpy as np
import pytest
import sympy as sp
from hard_scenes import BACKENDS, G, zeno_time
from scipy.integrate import quad, solve_ivp
from test_c_agreement_sustained import SCENES as AGREE
from test_sustained_closed_forms import dome, incline, landed_and_slid_on_the_incline, pendulum

import vcigen
from vcigen.analysis import fit_order

RULE = "lobatto3"
MAKERS = {"incline": incline, "dome": dome, "pendulum": pendulum}
THETA0 = 1.0  # the pendulum released at rest, 1 rad from the downward vertical
DOME_V0 = 0.1  # from the top of the dome, sideways


def _ball() -> vcigen.Model:
    x, y, xd, yd, e = sp.symbols("x y xd yd e")
    return vcigen.Model(
        name="l3_ball",
        q=[x, y],
        qdot=[xd, yd],
        lagrangian=(xd**2 + yd**2) / 2 - G * y,
        contacts={"floor": y},
        params={e: 0.5},
        restitution={"floor": e},
    )


MAKERS["ball"] = _ball


@cache
def sim(scene: str, backend: str) -> vcigen.Simulator:
    return vcigen.build(MAKERS[scene](), backend=backend, rule=RULE)


# ------------------------------------------------------------------ the pendulum on a bilateral rod


@cache
def pendulum_reference(t_end: float):
    """DOP853 at rtol 1e-13 on theta'' = -g sin(theta) (l = 1): the angle as a dense function of t."""
    sol = solve_ivp(
        lambda _t, y: [y[1], -G * math.sin(y[0])], (0.0, t_end), [THETA0, 0.0],
        method="DOP853", rtol=1e-13, atol=1e-14, dense_output=True,
    )  # fmt: skip
    return lambda t: sol.sol(t)[0]


def _pendulum_run(backend: str, h: float, t_end: float = 2.0) -> vcigen.Result:
    return sim("pendulum", backend).simulate(
        [math.sin(THETA0), -math.cos(THETA0)], [0.0, 0.0], h, t_end=t_end
    )


def _internal_points(backend: str, res: vcigen.Result) -> np.ndarray:
    """Each step's internal point ``q_m = q_k + h (v/2 + u)``, from the kernels' own constrained step
    (routine ``rattle``, unknowns ``(v, Lam, Lam_m, u)``) solved again from the recorded ``(q_k, p_k)``; its
    ``q_k + h v`` must be the recorded ``q_k+1``."""
    s = sim("pendulum", backend)
    k = s.kernels.bind(s.model.resolve_params(None))
    n, h, act = 2, res.h, np.ones(1)
    out = []
    for i in range(res.t.size - 1):
        x, resid = k.solve("rattle", np.zeros(n + 2 + n), res.q[i], res.p[i], h, act)
        assert resid <= 1e-12
        np.testing.assert_allclose(res.q[i] + h * x[:n], res.q[i + 1], rtol=0, atol=1e-13)
        out.append(res.q[i] + h * (x[:n] / 2 + x[n + 2 :]))
    return np.array(out)


@pytest.mark.parametrize("backend", BACKENDS)
def test_cartesian_pendulum_is_fourth_order_with_the_rod_held_at_every_node(backend):
    """Error of q against DOP853 over t in [0, 2] at h = 0.04 ... 0.005: fitted order 4.0 +- 0.3 (measured
    4.00 on both backends, 1.3e-8 at h = 0.01); x^2 + y^2 = 1 to round-off at the grid points and at every
    step's internal point; the velocity of p_k tangent to the rod.

    The mean tension over each step, -2 l (Lam + Lam_m + Lam')/h, is the mean of the closed form m g (3 cos
    theta - 2 cos theta0) along the reference (Gauss-Legendre) to O(h^4) (measured order 4.00); E_d stays
    within O(h^4) of its start (measured 4.1e-8 at h = 0.01)."""
    hs, errs, forces, energies = [0.04, 0.02, 0.01, 0.005], [], [], []
    theta = pendulum_reference(2.0)
    x, w = np.polynomial.legendre.leggauss(8)
    for h in hs:
        res = _pendulum_run(backend, h)
        th = theta(res.t)
        errs.append(np.abs(res.q - np.c_[np.sin(th), -np.cos(th)]).max())
        assert np.abs(res.q[:, 0] ** 2 + res.q[:, 1] ** 2 - 1).max() <= 1e-14
        assert np.abs(res.q[:, 0] * res.p[:, 0] + res.q[:, 1] * res.p[:, 1]).max() <= 1e-13
        tension = [
            G * (3 * np.cos(theta(t + (x + 1) * h / 2)) - 2 * math.cos(THETA0)) @ w / 2 for t in res.t[:-1]
        ]
        forces.append(np.abs(-2 * res.constraint_force[:, 0] - np.array(tension)).max())
        energies.append(np.abs(res.energy - res.energy[0]).max())
    print(f"\npendulum {backend}: h {hs}\n  q error {errs} order {fit_order(hs, errs):.2f}")
    print(f"  tension error {forces} order {fit_order(hs, forces):.2f}")
    print(f"  E_d deviation {energies} order {fit_order(hs, energies):.2f}")
    assert 3.7 <= fit_order(hs, errs) <= 4.3, errs
    assert errs[2] <= 2e-8, errs
    assert 3.7 <= fit_order(hs, forces) <= 4.3, forces
    assert 3.7 <= fit_order(hs, energies) <= 4.3, energies
    assert energies[2] <= 1e-7, energies


@pytest.mark.parametrize("backend", BACKENDS)
def test_the_internal_points_are_on_the_rod(backend):
    """psi(q_m) = 0 to solver tolerance at every step's internal point (h = 0.05, 40 steps); q_m lies near the
    state at the step's mid-time (as accurate as the grid points), not on the chord."""
    res = _pendulum_run(backend, 0.05)
    qm = _internal_points(backend, res)
    assert np.abs(qm[:, 0] ** 2 + qm[:, 1] ** 2 - 1).max() <= 1e-14
    chord = (res.q[1:] + res.q[:-1]) / 2
    assert np.abs(chord[:, 0] ** 2 + chord[:, 1] ** 2 - 1).max() >= 1e-4  # the chord's midpoint is not
    theta = pendulum_reference(2.0)
    th, grid = theta(res.t[:-1] + res.h / 2), theta(res.t)
    grid_err = np.abs(res.q - np.c_[np.sin(grid), -np.cos(grid)]).max()  # 8e-6
    # the state at the mid-time as accurate as the grid's (1.0e-5 measured)
    assert np.abs(qm - np.c_[np.sin(th), -np.cos(th)]).max() <= 2 * grid_err


def test_leaving_the_internal_point_free_would_be_second_order():
    """Why the internal point is held: the prototype (bench.lobatto3_constrained, no vcigen inside) with q_m
    free is order 2, with q_m on the rod order 4; vcigen's errors are the held prototype's."""
    from bench import lobatto3_constrained as proto

    sol = solve_ivp(
        lambda _t, y: [y[1], -G * math.sin(y[0])], (0.0, proto.T), [proto.THETA0, 0.0],
        method="DOP853", rtol=1e-13, atol=1e-13,
    )  # fmt: skip
    ref = np.array([math.sin(sol.y[0, -1]), -math.cos(sol.y[0, -1])])
    hs = [0.1, 0.05, 0.025]
    free = [np.abs(proto.run(False, h) - ref).max() for h in hs]
    held = [np.abs(proto.run(True, h) - ref).max() for h in hs]
    assert 1.8 <= fit_order(hs, free) <= 2.2 and 3.8 <= fit_order(hs, held) <= 4.2
    s = sim("pendulum", "casadi")
    for h, e in zip(hs, held):
        res = s.simulate([math.sin(proto.THETA0), -math.cos(proto.THETA0)], [0.0, 0.0], h, t_end=proto.T)
        assert np.abs(res.q[-1] - ref).max() == pytest.approx(e, rel=1e-6)


# ------------------------------------------------------------------ unilateral contacts held


@pytest.mark.parametrize("a", [0.3, 1.0])
@pytest.mark.parametrize("backend", BACKENDS)
def test_frictionless_incline_slides_exactly_and_is_pushed_with_g_cos_a(backend, a):
    """Launched up the slope at u = 2: s(t) = u t - g sin(a) t^2/2 exactly (the quadratic is in lobatto3's
    space), the normal force g cos(a) to round-off relative."""
    u, tangent = 2.0, np.array([math.cos(a), math.sin(a)])
    res = sim("incline", backend).simulate([0.0, 0.0], list(u * tangent), 0.01, t_end=1.0, params={"a": a})
    assert res.active.all() and res.n_impacts == 0 and not res.liftoffs
    s = u * res.t - G * math.sin(a) * res.t**2 / 2
    np.testing.assert_allclose(res.q, np.outer(s, tangent), rtol=0, atol=1e-13)
    np.testing.assert_allclose(res.p, np.outer(u - G * math.sin(a) * res.t, tangent), rtol=0, atol=1e-13)
    np.testing.assert_allclose(res.contact_force[:, 0], G * math.cos(a), rtol=1e-12, atol=0)
    np.testing.assert_allclose(res.energy, res.energy[0], rtol=0, atol=1e-12)


@pytest.mark.parametrize("backend", BACKENDS)
def test_plastic_landing_on_an_incline_then_slides_exactly(backend):
    """e = 0: dropped from (0, 1) with vx = 0.5 onto y = x tan(0.3): the impact at the closed-form time, the
    normal velocity removed, then the exact slide from the landing point with g sin(a) down the slope (the
    closed form of tests/test_sustained_closed_forms.py)."""
    a, h, q0, v0 = 0.3, 0.01, [0.0, 1.0], [0.5, 0.0]
    res = sim("incline", backend).simulate(q0, v0, h, t_end=1.0, params={"a": a})
    landed_and_slid_on_the_incline(res, a, h)


@pytest.mark.parametrize("backend", BACKENDS)
def test_resting_and_sliding_on_a_floor_the_force_is_m_g(backend):
    """Started on the floor at rest and sliding at 1: held all along, y = 0, x = t, lambda = m g to
    round-off."""
    for v0 in ([0.0, 0.0], [1.0, 0.0]):
        res = sim("ball", backend).simulate([0.0, 0.0], v0, 0.01, t_end=1.0)
        assert res.active.all() and res.n_impacts == 0
        np.testing.assert_allclose(res.q[:, 1], 0.0, rtol=0, atol=1e-15)
        np.testing.assert_allclose(res.q[:, 0], v0[0] * res.t, rtol=0, atol=1e-13)
        np.testing.assert_allclose(res.contact_force[:, 0], G, rtol=1e-13, atol=0)


@cache
def dome_lift_off_time() -> float:
    """The closed form: cos(theta*) = (2 g + v0^2)/(3 g), t* = int_0^theta* dtheta / sqrt(v0^2 + 2 g (1 -
    cos theta))."""
    theta = math.acos((2 * G + DOME_V0**2) / (3 * G))
    return quad(lambda th: 1 / math.sqrt(DOME_V0**2 + 2 * G * (1 - math.cos(th))), 0, theta, epsabs=1e-15)[0]


@pytest.mark.parametrize("backend", BACKENDS)
def test_lift_off_from_a_dome_is_located_to_order_four(backend):
    """Sliding off the unit circle from the top: the located lift-off time against the closed form; its error
    falls 16x from h = 0.01 to 0.005 (measured 3.09e-11, 1.93e-12) and stays below 4 h^4 at h = 0.01, 0.005,
    0.0025; held until then, free after, no impact; the slide on the circle against DOP853 on the angle to
    O(h^4) (8.9e-11 at h = 0.005)."""
    t_star = dome_lift_off_time()
    sol = solve_ivp(
        lambda _t, z: [z[1], G * math.sin(z[0])], (0.0, t_star), [0.0, DOME_V0],
        method="DOP853", rtol=1e-13, atol=1e-14, dense_output=True,
    )  # fmt: skip
    hs, errs, slides = [0.01, 0.005, 0.0025], [], []
    for h in hs:
        res = sim("dome", backend).simulate([0.0, 1.0], [DOME_V0, 0.0], h, t_end=1.4)
        assert res.n_impacts == 0 and len(res.liftoffs) == 1
        t = res.liftoffs[0][0]
        np.testing.assert_array_equal(res.active[:, 0], res.t <= t)
        errs.append(abs(t - t_star))
        on = res.t <= t_star
        th = sol.sol(res.t[on])[0]
        slides.append(np.abs(res.q[on] - np.c_[np.sin(th), np.cos(th)]).max())
        assert errs[-1] <= 4 * h**4, (h, errs[-1] / h**4)
    print(f"\ndome {backend}: h {hs}\n  lift-off error {errs}\n  slide error {slides}")
    assert 3.7 <= math.log2(errs[0] / errs[1]) <= 4.3, errs
    assert 3.7 <= fit_order(hs[:2], slides[:2]) <= 4.3 and slides[1] <= 2e-10, slides


# ------------------------------------------------------------------ the plastic entry (Zeno)


@pytest.mark.parametrize("h", [0.01, 0.001])
@pytest.mark.parametrize("e", [0.5, 0.8])
@pytest.mark.parametrize("backend", BACKENDS)
def test_zeno_sequence_comes_to_rest_and_slides(backend, e, h):
    """Dropped from y = 1 with vx = 0.3 on a floor with restitution e: bounces, then a plastic entry and the
    ball held to the end (t_inf + 0.5), no SolverError; y >= 0 to round-off, E_d never rises (to 1e-13), the
    held force m g, p_x untouched; the entry near the Zeno time (within 2 h/(1 - e), as under trapezoid)."""
    res = sim("ball", backend).simulate([0.0, 1.0], [0.3, 0.0], h, t_end=zeno_time(e) + 0.5, params={"e": e})
    assert res.t[-1] == pytest.approx(zeno_time(e) + 0.5, abs=h)
    assert [im.kind for im in res.impacts[:-1]] == ["restitution"] * (res.n_impacts - 1)
    assert res.impacts[-1].kind == "plastic" and res.n_impacts >= 5
    first = int(np.flatnonzero(res.active[:, 0])[0])
    assert res.active[first:, 0].all()
    assert abs(res.t[first] - zeno_time(e)) <= 2 * h / (1 - e) + h
    assert res.q[:, 1].min() >= -1e-12
    assert np.diff(res.energy).max() <= 1e-13
    held = res.active[1:, 0] & res.active[:-1, 0]
    np.testing.assert_allclose(res.contact_force[held, 0], G, rtol=1e-12, atol=0)
    assert np.all(res.p[:, 0] == 0.3)
    bounces = np.array([im.energy_before - im.energy_after for im in res.impacts[:-1]])
    v_sq = 2 * bounces / (1 - e * e)  # the k-th incoming speed e^k v1, v1^2 = 2 g
    np.testing.assert_allclose(v_sq, 2 * G * e ** (2 * np.arange(v_sq.size)), rtol=1e-6)


# ------------------------------------------------------------------ C = CasADi


@cache
def agreement_run(name: str, backend: str) -> vcigen.Result:
    make, q0, v0, h, t_end = AGREE[name]
    return vcigen.build(make(), backend=backend, rule=RULE).simulate(q0, v0, h, t_end=t_end)


# The star (e = 0.8, settling on a face: two rows of one contact held at its Abs kink) is chaotic: round-off
# between CasADi's SX and the printed C grows at its 38 impacts to 3.2e-6 in q; the events are the same.
AGREE_TOL = {"star": 1e-5}


@pytest.mark.parametrize("name", ["ball", "dome", "pendulum", "floor_wall", "star"])
def test_c_and_casadi_agree_through_sustained_contact(name):
    """tests/test_c_agreement_sustained.py's scenes under lobatto3 (a Zeno ball to rest, a dome lift-off, a
    pendulum rod striking a wall, a body held on a floor striking a wall, the star settling on a face): grid
    states, active sets, forces,
    impact logs and lift-offs the same to round-off (q to 1e-12)."""
    pytest.importorskip("vcigen.backends.c")
    c, ca = agreement_run(name, "c"), agreement_run(name, "casadi")
    assert c.q.shape == ca.q.shape
    diffs = [
        np.abs(a - b).max(initial=0.0)
        for a, b in ((c.q, ca.q), (c.p, ca.p), (c.contact_force, ca.contact_force))
    ]
    print(f"\n{name}: C - CasADi max |q| {diffs[0]:.1e} |p| {diffs[1]:.1e} |force| {diffs[2]:.1e}")
    tol = AGREE_TOL.get(name, 1e-12)
    np.testing.assert_allclose(c.q, ca.q, rtol=0, atol=tol)  # measured <= 7.4e-15 (star 3.2e-6)
    np.testing.assert_allclose(c.p, ca.p, rtol=0, atol=10 * tol)  # <= 2.3e-14
    np.testing.assert_array_equal(c.active, ca.active)
    np.testing.assert_allclose(c.contact_force, ca.contact_force, rtol=0, atol=1e3 * tol)  # <= 2.8e-12
    np.testing.assert_allclose(c.constraint_force, ca.constraint_force, rtol=0, atol=1e3 * tol)
    assert [(i.contact, i.kind, i.step) for i in c.impacts] == [
        (i.contact, i.kind, i.step) for i in ca.impacts
    ]
    assert [lo[1] for lo in c.liftoffs] == [lo[1] for lo in ca.liftoffs]
    np.testing.assert_allclose(
        [lo[0] for lo in c.liftoffs], [lo[0] for lo in ca.liftoffs], rtol=0, atol=max(1e-10, 100 * tol)
    )
    counts = [
        {k: v for k, v in r.stats.items() if k.startswith("impacts_") or k == "liftoffs"} for r in (c, ca)
    ]
    assert counts[0] == counts[1]


def test_the_agreement_scenes_exercise_what_they_are_for():
    pytest.importorskip("vcigen.backends.c")
    ball = agreement_run("ball", "c")
    assert ball.active[-1, 0] and ball.impacts[-1].kind == "plastic"
    assert len(agreement_run("dome", "c").liftoffs) == 1
    pend = agreement_run("pendulum", "c")
    assert np.all(np.abs(pend.constraint_force) > 0) and pend.n_impacts >= 2
    fw = agreement_run("floor_wall", "c")
    assert fw.active[:, 0].all() and any(i.contact == "wall" for i in fw.impacts)
    star = agreement_run("star", "c")
    assert star.stats["impacts_plastic"] >= 1 and star.active[-1, 0]
    assert star.q[-1, 1] == pytest.approx(0.5, abs=1e-12)  # resting on a face, L/2 above the floor


# ------------------------------------------------------------------ what lobatto3 still refuses


def test_friction_is_refused_by_name():
    x, y, xd, yd = sp.symbols("x y xd yd")
    model = vcigen.Model(
        name="l3_fric",
        q=[x, y],
        qdot=[xd, yd],
        lagrangian=(xd**2 + yd**2) / 2 - G * y,
        contacts={"floor": y},
        friction={"floor": (0.5, x)},
    )
    for build in (lambda: vcigen.derive(model, RULE), lambda: vcigen.build(model, backend="c", rule=RULE)):
        with pytest.raises(ValueError, match="lobatto3.*friction"):
            build()


@pytest.mark.parametrize("name", ["dome", "pendulum"])
def test_python_stepper_on_c_kernels_is_the_c_loop(name):
    """vcigen.sustained's chain on the C kernels' single calls (rattle, rattle_end, rattle_project) is the
    C loop's: the same grid to 1e-12, the same events."""
    pytest.importorskip("vcigen.backends.c")
    from test_c_agreement_sustained import assert_python_stepper_is_the_c_loop

    s = vcigen.build(AGREE[name][0](), backend="c", rule=RULE)
    assert_python_stepper_is_the_c_loop(s, AGREE[name], agreement_run(name, "c"))


# ------------------------------------------------------------------ forces with rows held


def _damped(kind: str) -> vcigen.Model:
    """Drag F = -c qdot (c = 0.3) on the pendulum rod or on a ball on a floor (``floor_e``: e = 0.5)."""
    x, y, xd, yd = sp.symbols("x y xd yd")
    held = {"constraints": {"rod": x**2 + y**2 - 1}} if kind == "rod" else {"contacts": {"floor": y}}
    if kind == "floor_e":  # with restitution 0.5
        held |= {"params": {sp.Symbol("e"): 0.5}, "restitution": {"floor": sp.Symbol("e")}}
    return vcigen.Model(
        name=f"l3_drag_{kind}",
        q=[x, y],
        qdot=[xd, yd],
        lagrangian=(xd**2 + yd**2) / 2 - G * y,
        forces=[-0.3 * xd, -0.3 * yd],
        **held,
    )


@pytest.mark.parametrize("backend", BACKENDS)
def test_forces_on_held_rows_are_fourth_order_with_the_work_booked(backend):
    """Drag on the pendulum rod (t = 3): q against DOP853 on theta'' = -g sin(theta) - c theta' and
    ``energy_balance()`` both order 4.0 +- 0.3 (the work of a held step at its held internal point,
    ``vcigen.booking._held_stationarity``; at the free one the balance was order 2.00: 6.7e-3 ... 4.2e-4).
    A ball sliding on a floor against drag: x = v0 (1 - exp(-c t))/c to O(h^4), balance <= 1e-11."""
    sol = solve_ivp(
        lambda _t, z: [z[1], -G * math.sin(z[0]) - 0.3 * z[1]], (0.0, 3.0), [THETA0, 0.0],
        method="DOP853", rtol=1e-13, atol=1e-14, dense_output=True,
    )  # fmt: skip
    s = vcigen.build(_damped("rod"), backend=backend, rule=RULE)
    hs, errs, bal = [0.04, 0.02, 0.01], [], []
    for h in hs:
        res = s.simulate([math.sin(THETA0), -math.cos(THETA0)], [0.0, 0.0], h, t_end=3.0)
        th = sol.sol(res.t)[0]
        errs.append(np.abs(res.q - np.c_[np.sin(th), -np.cos(th)]).max())
        bal.append(np.abs(res.energy_balance()).max())
    print(f"\ndrag on a rod {backend}: q error {errs}, balance {bal}")
    assert 3.7 <= fit_order(hs, errs) <= 4.3 and 3.7 <= fit_order(hs, bal) <= 4.3, (errs, bal)
    floor = vcigen.build(_damped("floor"), backend=backend, rule=RULE)
    res = floor.simulate([0.0, 0.0], [1.0, 0.0], 0.01, t_end=3.0)
    assert res.active.all() and res.n_impacts == 0
    np.testing.assert_allclose(res.q[:, 0], (1 - np.exp(-0.3 * res.t)) / 0.3, rtol=0, atol=1e-12)
    assert np.abs(res.energy_balance()).max() <= 1e-11


@pytest.mark.parametrize("backend", BACKENDS)
def test_a_damped_ball_bouncing_to_rest_balances_its_energy(backend):
    """Drag on a ball with e = 0.5 dropped from y = 1 (t = 4): bounces, a plastic entry, then held sliding.
    ``energy_balance()`` (the held steps' work at their held internal points, the plastic entry's logged
    energy to the held segment's start) falls like h^4 but for the impact count (5, 6, 7 impacts): measured
    1.0e-8, 5.9e-10, 6.3e-11 at h = 0.02, 0.01, 0.005 (without the plastic entry's share, 3.4e-7 at 0.01)."""
    floor = vcigen.build(_damped("floor_e"), backend=backend, rule=RULE)
    hs, bal = [0.02, 0.01, 0.005], []
    for h in hs:
        res = floor.simulate([0.0, 1.0], [0.3, 0.0], h, t_end=4.0)
        assert res.impacts[-1].kind == "plastic" and res.active[-1, 0] and res.q[:, 1].min() >= -1e-12
        bal.append(np.abs(res.energy_balance()).max())
    print(f"\ndamped Zeno {backend}: balance {bal}")
    assert fit_order(hs, bal) >= 3.3 and bal[1] <= 2e-9, bal
