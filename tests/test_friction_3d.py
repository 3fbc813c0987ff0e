"""Coulomb friction with two tangents (the isotropic cone of a 3-D contact; MATH.md *Friction*) on both
backends, against closed forms and scipy.

* A puck (a point mass on the plane z = 0, tangents ``(x, y)``) sliding at ``(vx, vy)`` decelerates at
  ``mu g`` along a straight line and stops after ``v^2/(2 mu g)`` at ``v/(mu g)``.
* On an incline (angle ``a`` about the x axis, ``tan a < mu``) with a transverse velocity its path curves:
  against scipy's Coulomb ODE ``vdot = -g sin a e_y - mu g cos a v/|v|`` with the stop as an event.
* A ball (``x, y, z`` and rotation angles ``ax, ay`` about x and y, sliding velocity ``(xd - r ayd, yd + r
  axd)``) bouncing on a rough floor leaves with Coulomb's impulse law: the stick impulse if it fits in the
  cone ``mu P_n``, else ``-mu P_n u/|u|`` along the incoming sliding ``u``.
* A turning rod's end hitting the floor (the tangents coupled to the normal through the rotation) leaves with
  the least-energy impulse over the cone under Newton's law, found independently by scipy's SLSQP.
* The impulse over the cone (:func:`vcigen.friction.cone_impulse`) against scipy's SLSQP; friction never adds
  energy (random rough 3-D boxes); bad friction is refused; C = CasADi.
"""

from __future__ import annotations

import math
from functools import cache

import numpy as np
import pytest
import sympy as sp
from hard_scenes import BACKENDS, G
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from scipy.integrate import solve_ivp
from scipy.optimize import brentq, minimize

import vcigen
from vcigen.friction import cone_impulse

MU = 0.4
MASS, INERTIA, RADIUS, BALL_MU, REST = 1.0, 0.4, 1.0, 0.3, 0.7


def puck() -> vcigen.Model:
    """A unit point mass on the plane z = 0 tilted by ``a`` about the x axis, two-tangent friction ``mu``."""
    x, y, z, xd, yd, zd = sp.symbols("x y z xd yd zd")
    g, mu, a = sp.symbols("g mu a")
    return vcigen.Model(
        name="rough_puck",
        q=[x, y, z],
        qdot=[xd, yd, zd],
        lagrangian=(xd**2 + yd**2 + zd**2) / 2 - g * (z * sp.cos(a) + y * sp.sin(a)),
        contacts={"floor": z},
        params={g: G, mu: MU, a: 0.0},
        friction={"floor": (mu, (x, y))},
    )


def ball() -> vcigen.Model:
    """A ball of radius r above a rough floor: its centre (x, y, z) and rotation angles (ax, ay) about the x
    and y axes (an isotropic inertia I; the spin about z does not slide), restitution e and friction mu."""
    x, y, z, ax, ay = sp.symbols("x y z ax ay")
    xd, yd, zd, axd, ayd = sp.symbols("xd yd zd axd ayd")
    m, inertia, r, g, mu, e = sp.symbols("m I r g mu e")
    return vcigen.Model(
        name="rough_ball",
        q=[x, y, z, ax, ay],
        qdot=[xd, yd, zd, axd, ayd],
        lagrangian=m / 2 * (xd**2 + yd**2 + zd**2) + inertia / 2 * (axd**2 + ayd**2) - m * g * z,
        contacts={"floor": z - r},
        params={m: MASS, inertia: INERTIA, r: RADIUS, g: G, mu: BALL_MU, e: REST},
        restitution={"floor": e},
        friction={"floor": (mu, (x - r * ay, y + r * ax))},
    )


def rough_box_3d() -> vcigen.Model:
    """A unit particle in the unit cube under gravity g along -z, every wall with restitution e and
    two-tangent friction mu."""
    x, y, z, xd, yd, zd = sp.symbols("x y z xd yd zd")
    e, mu, g = sp.symbols("e mu g")
    walls = {
        "x0": (x, (y, z)),
        "x1": (1 - x, (y, z)),
        "y0": (y, (x, z)),
        "y1": (1 - y, (x, z)),
        "z0": (z, (x, y)),
        "z1": (1 - z, (x, y)),
    }
    return vcigen.Model(
        name="rough_box_3d",
        q=[x, y, z],
        qdot=[xd, yd, zd],
        lagrangian=(xd**2 + yd**2 + zd**2) / 2 - g * z,
        contacts={k: phi for k, (phi, _) in walls.items()},
        params={e: 1.0, mu: 0.5, g: 0.0},
        restitution=dict.fromkeys(walls, e),
        friction={k: (mu, tan) for k, (_, tan) in walls.items()},
    )


def rod() -> vcigen.Model:
    """A unit rod of length 1 (I = 1/12) turning about the y axis, its end ``(x + cos(th)/2, y,
    z - sin(th)/2)`` on a rough floor: the cone's tangents ``(x + cos(th)/2, y)`` are not M-orthogonal to the
    normal (b != 0)."""
    x, y, z, th, xd, yd, zd, thd = sp.symbols("x y z th xd yd zd thd")
    e, mu = sp.symbols("e mu")
    return vcigen.Model(
        name="rough_rod",
        q=[x, y, z, th],
        qdot=[xd, yd, zd, thd],
        lagrangian=(xd**2 + yd**2 + zd**2) / 2 + thd**2 / 24 - G * z,
        contacts={"end": z - sp.sin(th) / 2},
        params={e: 0.5, mu: 0.5},
        restitution={"end": e},
        friction={"end": (mu, (x + sp.cos(th) / 2, y))},
    )


def mixed() -> vcigen.Model:
    """A particle on a floor with a cone (two tangents) and a wall with one tangent."""
    x, y, z, xd, yd, zd = sp.symbols("x y z xd yd zd")
    return vcigen.Model(
        name="rough_corner",
        q=[x, y, z],
        qdot=[xd, yd, zd],
        lagrangian=(xd**2 + yd**2 + zd**2) / 2 - G * z,
        contacts={"floor": z, "wall": 1 - x},
        restitution={"floor": 0.5, "wall": 0.6},
        friction={"floor": (0.3, (x, y)), "wall": (0.5, z)},
    )


@cache
def sim(name: str, backend: str) -> vcigen.Simulator:
    models = {"puck": puck, "ball": ball, "box": rough_box_3d, "rod": rod, "mixed": mixed}
    return vcigen.build(models[name](), backend=backend)


# -- sustained contact -------------------------------------------------------------------------------------
@pytest.mark.parametrize("backend", BACKENDS)
def test_puck_slides_straight_to_a_stop_after_v2_over_2_mu_g(backend):
    """Sliding at (vx, vy) on a level floor: it decelerates at mu g along v, exactly; it stops at v/(mu g)
    after v^2/(2 mu g) along v and sticks; friction's work is -v^2/2."""
    vx, vy = 1.2, -0.9
    v = math.hypot(vx, vy)
    ts, dist = v / (MU * G), v * v / (2 * MU * G)
    for h in (0.01, 0.003):
        res = sim("puck", backend).simulate(q0=[0.0, 0.0, 0.0], v0=[vx, vy, 0.0], h=h, t_end=1.0)
        t = res.t
        s = np.where(t < ts, v * t - MU * G * t**2 / 2, dist)
        exact = np.stack([s * vx / v, s * vy / v], 1)
        assert np.max(np.abs(res.q[:, :2] - exact)) < 1e-12
        assert np.all(res.active[:, 0]) and np.max(np.abs(res.q[:, 2])) < 1e-12
        assert abs(res.work.sum() + v * v / 2) < 1e-12
        assert np.max(np.abs(res.p[t > ts + h, :2])) < 1e-15


@pytest.mark.parametrize("backend", BACKENDS)
@pytest.mark.parametrize("slope", [0.5, 1.5])
def test_puck_at_rest_on_an_incline_sticks_or_slides_downhill(backend, slope):
    """At rest on an incline with tan a = slope mu: it stays put (slope < 1), or the stick breaks at once and
    it slides straight downhill at g (sin a - mu cos a), exactly (slope > 1)."""
    angle = math.atan(slope * MU)
    res = sim("puck", backend).simulate(
        q0=[0.0, 0.0, 0.0], v0=[0.0, 0.0, 0.0], h=0.01, t_end=1.0, params={"a": angle}
    )
    acc = G * (math.sin(angle) - MU * math.cos(angle)) if slope > 1 else 0.0
    np.testing.assert_allclose(res.q[:, 1], -acc * res.t**2 / 2, rtol=0, atol=1e-13)
    assert np.max(np.abs(res.q[:, 0])) == 0.0 and np.all(res.active[:, 0])


@cache
def incline_reference(angle: float, vx: float, vy: float):
    """scipy's Coulomb ODE on the incline (tight tolerances), the stop (|v| -> 0) located as an event:
    ``(dense solution, stop time, stop point)``."""
    ca, sa = math.cos(angle), math.sin(angle)

    def rhs(t, s):
        speed = math.hypot(s[2], s[3])
        return [s[2], s[3], -MU * G * ca * s[2] / speed, -G * sa - MU * G * ca * s[3] / speed]

    def stop(t, s):
        return math.hypot(s[2], s[3]) - 1e-11

    stop.terminal, stop.direction = True, -1
    ref = solve_ivp(
        rhs,
        (0.0, 5.0),
        [0.0, 0.0, vx, vy],
        method="DOP853",
        rtol=1e-13,
        atol=1e-15,
        events=stop,
        dense_output=True,
    )
    return ref.sol, float(ref.t_events[0][0]), ref.y_events[0][0][:2]


@pytest.mark.parametrize("backend", BACKENDS)
def test_puck_on_an_incline_curves_to_a_stop_as_scipy(backend):
    """On an incline with tan a = mu/2, launched across it: the sliding direction turns downhill while
    friction slows it, and it stops (then sticks, tan a < mu). The path agrees with scipy's Coulomb ODE to
    O(h^2)."""
    angle, vx, vy = math.atan(MU / 2), 1.5, 0.5
    sol, ts, q_stop = incline_reference(angle, vx, vy)
    assert q_stop[0] > 0.25 and abs(q_stop[1]) < 0.1  # it curves: downhill turns it back towards y = 0
    errs = []
    for h in (0.01, 0.005):
        res = sim("puck", backend).simulate(
            q0=[0.0, 0.0, 0.0], v0=[vx, vy, 0.0], h=h, t_end=1.0, params={"a": angle}
        )
        exact = np.array([sol(t)[:2] if t < ts else q_stop for t in res.t])
        errs.append(float(np.max(np.abs(res.q[:, :2] - exact))))
        assert np.all(res.active[:, 0])
        late = res.t > ts + 2 * h
        assert np.max(np.abs(res.p[late, :2])) < 1e-14  # stuck on the incline
        assert np.all(res.work <= 1e-15)
    assert errs[1] < 3e-5 and errs[1] < errs[0] / 3.5, errs


@pytest.mark.parametrize("backend", BACKENDS)
def test_puck_on_a_steep_incline_slides_downhill_as_scipy(backend):
    """tan a > mu: it never stops; launched across the slope its sliding turns downhill (scipy, O(h^2))."""
    angle, vx, vy = math.atan(1.5 * MU), 1.0, 0.0
    ca, sa = math.cos(angle), math.sin(angle)

    def rhs(t, s):
        speed = math.hypot(s[2], s[3])
        return [s[2], s[3], -MU * G * ca * s[2] / speed, -G * sa - MU * G * ca * s[3] / speed]

    ref = solve_ivp(
        rhs, (0.0, 1.0), [0.0, 0.0, vx, vy], method="DOP853", rtol=1e-13, atol=1e-15, dense_output=True
    )
    errs = []
    for h in (0.01, 0.005):
        res = sim("puck", backend).simulate(
            q0=[0.0, 0.0, 0.0], v0=[vx, vy, 0.0], h=h, t_end=1.0, params={"a": angle}
        )
        errs.append(float(np.max(np.abs(res.q[:, :2] - ref.sol(res.t)[:2].T))))
    assert errs[1] < 6e-5 and errs[1] < errs[0] / 3.5, errs


# -- impacts -----------------------------------------------------------------------------------------------
def coulomb_ball(v, w, rest: float = REST):
    """Velocity and spin after an impact of the ball on the floor by Coulomb's law: ``(v+, w+, rolls)``."""
    pn = MASS * (1 + rest) * (-v[2])
    slide = np.array([v[0] - RADIUS * w[1], v[1] + RADIUS * w[0]])
    stick = -slide / (1 / MASS + RADIUS**2 / INERTIA)
    rolls = math.hypot(*stick) <= BALL_MU * pn
    pt = stick if rolls else -BALL_MU * pn * slide / math.hypot(*slide)
    v_out = np.array([v[0] + pt[0] / MASS, v[1] + pt[1] / MASS, -rest * v[2]])
    w_out = np.array([w[0] + RADIUS * pt[1] / INERTIA, w[1] - RADIUS * pt[0] / INERTIA])
    return v_out, w_out, rolls


@pytest.mark.parametrize("spin, rolls", [((1.0, 4.0), True), ((3.0, -20.0), False)])
@pytest.mark.parametrize("backend", BACKENDS)
def test_ball_leaves_the_floor_with_coulombs_velocity_and_spin(backend, spin, rolls):
    """Dropped from height 1 with (vx, vy) = (2, -1) and spin (wx, wy): after the first impact the velocity
    and spin (constant in flight) are Coulomb's to O(h^2), rolling or slipping throughout; the energy lost is
    the impulse law's."""
    v0, w0 = np.array([2.0, -1.0, -math.sqrt(2 * G)]), np.array(spin)
    v1, w1, roll = coulomb_ball(v0, w0)
    assert roll == rolls
    errs = []
    for h in (0.01, 0.005):
        res = sim("ball", backend).simulate(
            q0=[0.0, 0.0, 2.0, 0.0, 0.0], v0=[2.0, -1.0, 0.0, *spin], h=h, t_end=0.9
        )
        assert len(res.impacts) == 1
        k = res.impacts[0].step + 2
        vel, w = res.p[k, :2] / MASS, res.p[k, 3:] / INERTIA
        errs.append(max(np.max(np.abs(vel - v1[:2])), np.max(np.abs(w - w1))))
        if rolls:  # no sliding after the impact
            assert math.hypot(vel[0] - RADIUS * w[1], vel[1] + RADIUS * w[0]) < 1e-3
        else:  # the tangential impulse is on the cone's edge, against the incoming sliding
            slide_in = np.array([v0[0] - RADIUS * w0[1], v0[1] + RADIUS * w0[0]])
            pt = res.p[k, :2] - MASS * v0[:2]
            assert abs(pt @ slide_in + math.hypot(*pt) * math.hypot(*slide_in)) < 1e-9 * math.hypot(*pt) * 30
        k_in = 0.5 * MASS * v0 @ v0 + 0.5 * INERTIA * w0 @ w0
        k_out = 0.5 * MASS * v1 @ v1 + 0.5 * INERTIA * w1 @ w1
        im = res.impacts[0]
        assert abs((im.energy_before - im.energy_after) - (k_in - k_out)) < 1e-2 * (k_in - k_out)
    assert errs[1] < 1e-4 and errs[1] < errs[0] / 3, errs


def rod_reference(v0, th0: float, e: float, mu: float):
    """The rod's end impact, independently: the free flight to the floor (brentq), then the impulse of least
    kinetic energy over Coulomb's cone under Newton's law by scipy's SLSQP: ``(velocity after, stick?)``."""
    vx, vy, w = v0
    minv = np.diag([1.0, 1.0, 1.0, 12.0])
    ts = brentq(lambda t: 1.0 - G * t * t / 2 - math.sin(th0 + w * t) / 2, 1e-9, 2.0)
    th = th0 + w * ts
    qd = np.array([vx, vy, -G * ts, w])
    n = np.array([0.0, 0.0, 1.0, -math.cos(th) / 2])
    tg = np.array([[1.0, 0.0, 0.0, -math.sin(th) / 2], [0.0, 1.0, 0.0, 0.0]])

    def after(mt):
        mun = (-(1 + e) * (n @ qd) - n @ minv @ tg.T @ mt) / (n @ minv @ n)  # Newton on the normal
        return qd + minv @ (mun * n + tg.T @ mt), mun

    def kinetic(mt):
        v = after(mt)[0]
        return 0.5 * v @ np.linalg.solve(minv, v)

    cone = {"type": "ineq", "fun": lambda mt: mu * after(mt)[1] - math.sqrt(mt @ mt + 1e-30)}
    best = min(
        (
            minimize(kinetic, x0, constraints=[cone], method="SLSQP", options={"ftol": 1e-15, "maxiter": 500})
            for x0 in (np.zeros(2), np.array([0.1, 0.1]), np.array([-0.1, 0.2]))
        ),
        key=lambda r: r.fun if r.success else math.inf,
    )
    return after(best.x)[0], math.hypot(*best.x) < mu * after(best.x)[1] * (1 - 1e-6)


@pytest.mark.parametrize(
    "case, sticks", [(((1.0, 0.5, 2.0), 0.7, 0.5, 0.3), True), (((3.0, 2.0, 0.5), 0.4, 0.3, 0.2), False)]
)
@pytest.mark.parametrize("backend", BACKENDS)
def test_rod_end_impact_with_coupled_normal_against_slsqp(backend, case, sticks):
    """A turning rod's end hits the floor, the tangents coupled to the normal through the rotation (b != 0:
    the normal impulse depends on the tangential one): its velocity and spin after the impact are the
    SLSQP minimiser's to O(h^2), sticking or slipping."""
    v0, th0, e, mu = case
    v1, stick = rod_reference(v0, th0, e, mu)
    assert stick == sticks
    errs = []
    for h in (0.01, 0.0025):
        res = sim("rod", backend).simulate(
            q0=[0.0, 0.0, 1.0, th0], v0=[v0[0], v0[1], 0.0, v0[2]], h=h, t_end=0.45, params={"e": e, "mu": mu}
        )
        k = res.impacts[0].step + 2
        vel = res.p[k] * np.array([1.0, 1.0, 1.0, 12.0])
        errs.append(float(np.max(np.abs(vel[[0, 1, 3]] - v1[[0, 1, 3]]))))
        assert res.impacts[0].energy_after < res.impacts[0].energy_before
    assert errs[1] < 1e-3 and errs[1] < errs[0] / 12, errs


@pytest.mark.parametrize("backend", BACKENDS)
def test_ball_set_down_sliding_rolls_when_friction_has_matched_its_spin(backend):
    """A ball set down on the floor sliding with spin: the sliding velocity u shrinks along a fixed direction
    at mu g (1 + m r^2 / I) while the centre decelerates at mu g along -u/|u|, until it rolls at
    t* = |u0| / (mu g (1 + m r^2 / I)); then it rolls on straight at constant velocity. Exact."""
    v0, w0 = np.array([1.0, 0.5]), np.array([2.0, -1.5])
    u0 = np.array([v0[0] - RADIUS * w0[1], v0[1] + RADIUS * w0[0]])
    decel = BALL_MU * G * u0 / math.hypot(*u0)
    ts = math.hypot(*u0) / (BALL_MU * G * (1 + MASS * RADIUS**2 / INERTIA))
    res = sim("ball", backend).simulate(
        q0=[0.0, 0.0, RADIUS, 0.0, 0.0], v0=[*v0, 0.0, *w0], h=0.01, t_end=1.0
    )
    t = res.t[:, None]
    tc = np.minimum(t, ts)
    exact = v0 * tc - decel * tc**2 / 2 + (v0 - decel * ts) * np.maximum(t - ts, 0.0)
    assert np.max(np.abs(res.q[:, :2] - exact)) < 1e-12
    late = res.t > ts + 0.02
    np.testing.assert_allclose(
        res.p[late, :2] / MASS, np.broadcast_to(v0 - decel * ts, (late.sum(), 2)), atol=1e-12
    )
    w = res.p[late, 3:] / INERTIA
    np.testing.assert_allclose(res.p[late, 0] / MASS - RADIUS * w[:, 1], 0.0, atol=1e-12)
    np.testing.assert_allclose(res.p[late, 1] / MASS + RADIUS * w[:, 0], 0.0, atol=1e-12)
    assert np.all(res.active[:, 0])


def test_cone_impulse_is_the_minimiser_over_the_cone():
    """The impulse law's minimisation against scipy's SLSQP on random instances (b = 0 and b != 0, narrow and
    wide cones, mu_f |b| >= 1 included): feasible, and never above SLSQP's minimum."""
    rng = np.random.default_rng(7)
    checked = 0
    for _ in range(200):
        low = rng.normal(size=(2, 2))
        h = low @ low.T + 0.05 * np.eye(2)
        g = rng.normal(size=2) * rng.choice([0.1, 1.0, 10.0])
        b = rng.normal(size=2) * rng.choice([0.0, 0.3, 1.0])
        mf, a = rng.uniform(0.05, 2.0), rng.uniform(0.1, 3.0)
        m = np.array(cone_impulse(tuple(g), (h[0, 0], h[0, 1], h[1, 1]), tuple(b), mf, a))
        assert mf * (a - b @ m) - np.linalg.norm(m) >= -1e-12 * (1 + np.linalg.norm(m))

        def energy(x, g=g, h=h):
            return g @ x + 0.5 * x @ h @ x

        def inside(x, b=b, mf=mf, a=a):
            return mf * (a - b @ x) - math.sqrt(x @ x + 1e-30)

        best = None
        for x0 in (np.zeros(2), m, rng.normal(size=2)):
            r = minimize(
                energy,
                x0,
                constraints=[{"type": "ineq", "fun": inside}],
                method="SLSQP",
                options={"ftol": 1e-15, "maxiter": 500},
            )
            if r.success and inside(r.x) > -1e-9 and (best is None or r.fun < best):
                best = r.fun
        if best is None:
            continue
        checked += 1
        assert energy(m) <= best + 1e-10 * (1 + abs(best))
    assert checked > 150


@pytest.mark.parametrize("backend", BACKENDS)
@settings(
    max_examples=10,
    deadline=None,
    derandomize=True,
    suppress_health_check=[HealthCheck.function_scoped_fixture],
)
@given(
    x=st.floats(0.1, 0.9),
    y=st.floats(0.1, 0.9),
    z=st.floats(0.1, 0.9),
    theta=st.floats(0.0, math.pi),
    phi=st.floats(0.0, 2 * math.pi),
    e=st.floats(0.0, 1.0),
    mu=st.floats(0.0, 1.5),
    g=st.sampled_from([0.0, G]),
)
def test_cone_friction_never_adds_energy(backend, x, y, z, theta, phi, e, mu, g):
    """Random rough 3-D boxes, with and without gravity (then the particle lands, slides and sticks): no
    impact raises the energy, E_d never rises by more than the jump's resolution, friction's work <= 0."""
    direction = [math.sin(theta) * math.cos(phi), math.sin(theta) * math.sin(phi), math.cos(theta)]
    res = sim("box", backend).simulate(
        q0=[x, y, z], v0=[2 * d for d in direction], h=0.01, t_end=3.0, params={"e": e, "mu": mu, "g": g}
    )
    for im in res.impacts:
        assert im.energy_after <= im.energy_before + 1e-12
    assert np.all(res.work <= 0.0)
    # E_d's own jumps at a plastic entry or a landing are within the jump's resolution (g h)^2 / 8 (MATH.md)
    assert np.all(np.diff(res.energy) <= (g * 0.01) ** 2 / 8 + 1e-9 * (1 + abs(res.energy[0])))


def test_bad_cone_friction_is_refused():
    x, y, z, xd, yd, zd = sp.symbols("x y z xd yd zd")
    base = dict(
        name="bad",
        q=[x, y, z],
        qdot=[xd, yd, zd],
        lagrangian=(xd**2 + yd**2 + zd**2) / 2,
        contacts={"floor": z},
    )
    with pytest.raises(ValueError, match="has 3 tangents"):
        vcigen.Model(friction={"floor": (0.3, (x, y, z))}, **base)
    with pytest.raises(ValueError, match="has 0 tangents"):
        vcigen.Model(friction={"floor": (0.3, ())}, **base)
    with pytest.raises(ValueError, match="its two tangents are the same"):
        vcigen.Model(friction={"floor": (0.3, (x, x))}, **base)
    with pytest.raises(ValueError, match="must be an expression of the coordinates"):
        vcigen.Model(friction={"floor": (0.3, (x, yd))}, **base)
    with pytest.raises(ValueError, match="two tangents and the contact's normal grad phi are dependent"):
        vcigen.Model(friction={"floor": (0.3, (x, 2 * x + z))}, **base)
    tangents = vcigen.Model(friction={"floor": (0.3, (x, y))}, **base).tangents_of
    assert [str(t) for t in tangents["floor"]] == ["x", "y"]


def test_c_equals_casadi_with_cones():
    """A spinning ball bouncing on the floor until it rolls, a puck curving to a stop on an incline, and a
    particle between a floor with a cone and a wall with one tangent: the same trajectories, impacts, work
    and active sets on both backends."""
    scenes = {
        "ball": (dict(q0=[0.0, 0.0, 2.0, 0.0, 0.0], v0=[2.0, -1.0, 0.0, 3.0, -20.0], h=0.01, t_end=3.0), 5),
        "puck": (
            dict(q0=[0.0, 0.0, 0.0], v0=[1.5, 0.5, 0.0], h=0.01, t_end=1.0, params={"a": math.atan(MU / 2)}),
            0,
        ),
        "mixed": (dict(q0=[0.2, 0.0, 0.5], v0=[3.0, 1.0, 0.0], h=0.01, t_end=3.0), 3),
    }
    for name, (run, impacts) in scenes.items():
        a, b = (sim(name, bk).simulate(**run) for bk in ("casadi", "c"))
        assert len(a.impacts) == len(b.impacts) >= impacts
        np.testing.assert_allclose(a.q, b.q, rtol=0, atol=1e-10)
        np.testing.assert_allclose(a.p, b.p, rtol=0, atol=1e-10)
        np.testing.assert_allclose(a.work, b.work, rtol=0, atol=1e-10)
        assert np.array_equal(a.active, b.active)
        assert all(im.energy_after <= im.energy_before + 1e-12 for im in a.impacts)
