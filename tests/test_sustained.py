"""Sustained contact (MATH.md, *Sustained contact*; API.md, *Contact regimes*), on both backends.

By default (``Tolerances(grazing="contact", rest=1.0)``) an impact the energy-preserving jump
cannot resolve is plastic and the contact becomes active: a constrained (RATTLE) step holds
``phi = 0`` with a multiplier ``lambda >= 0`` (``res.contact_force``, ``m g`` at rest), released
where the continuous force vanishes. Every reference here is a closed form (Newton's impulse
law, the weight, a straight line, energy) or scipy's ``solve_ivp`` (DOP853, rtol = atol = 1e-12,
with event location) on the reduced equations of motion, never vcigen itself.
"""

from __future__ import annotations

import math
from functools import cache

import numpy as np
import pytest
import sympy as sp
from hard_scenes import BACKENDS, G, min_phi, parabola, simulator
from scipy.integrate import solve_ivp
from scipy.special import ellipk
from test_hard_cases import GRAZING

import vcigen
from vcigen.analysis import fit_order

STRICT = vcigen.Tolerances(grazing="error")  # the paper's method alone
ROD_L = 0.5  # half-length of the rod (vertices at +-l along it)
ROD_I = (2 * ROD_L) ** 2 / 12  # uniform rod of unit mass, length 2 l


# ------------------------------------------------------------------ models


def rod() -> vcigen.Model:
    """A uniform rod, q = (x, y, theta), M = diag(1, 1, I), vertices at y -+ l sin(theta) over a floor."""
    x, y, th, xd, yd, thd = sp.symbols("x y theta xd yd thetad")
    half, e = sp.symbols("l e", positive=True)
    return vcigen.Model(
        name="rod",
        q=[x, y, th],
        qdot=[xd, yd, thd],
        lagrangian=(xd**2 + yd**2) / 2 + (2 * half) ** 2 / 24 * thd**2 - G * y,
        contacts={"left": y - half * sp.sin(th), "right": y + half * sp.sin(th)},
        params={half: ROD_L, e: 0.0},
        restitution={"left": e, "right": e},
    )


def floor_wall() -> vcigen.Model:
    """A unit particle on the floor y >= 0 in front of the wall x <= 1 (restitution e on the wall)."""
    x, y, xd, yd = sp.symbols("x y xd yd")
    e = sp.Symbol("e")
    return vcigen.Model(
        name="floor_wall",
        q=[x, y],
        qdot=[xd, yd],
        lagrangian=(xd**2 + yd**2) / 2 - G * y,
        contacts={"floor": y, "wall": 1 - x},
        params={e: 1.0},
        restitution={"wall": e},
    )


def bowl() -> vcigen.Model:
    """A unit particle inside the frictionless unit circle, 1 - x^2 - y^2 >= 0, under gravity."""
    x, y, xd, yd = sp.symbols("x y xd yd")
    return vcigen.Model(
        name="bowl",
        q=[x, y],
        qdot=[xd, yd],
        lagrangian=(xd**2 + yd**2) / 2 - G * y,
        contacts={"rim": 1 - x**2 - y**2},
    )


def rod_wall() -> vcigen.Model:
    """A unit bob on a unit rod (bilateral, Cartesian), a wall ``x >= a`` (restitution e) by its bottom."""
    x, y, xd, yd = sp.symbols("x y xd yd")
    a, e = sp.symbols("a e")
    return vcigen.Model(
        name="rod_wall",
        q=[x, y],
        qdot=[xd, yd],
        lagrangian=(xd**2 + yd**2) / 2 - G * y,
        contacts={"wall": x - a},
        constraints={"rod": x**2 + y**2 - 1},
        params={a: 0.3, e: 0.16},
        restitution={"wall": e},
    )


MAKERS = {"rod": rod, "floor_wall": floor_wall, "bowl": bowl, "rod_wall": rod_wall}


@cache
def sim(scene: str, backend: str, tol: vcigen.Tolerances | None = None) -> vcigen.Simulator:
    """Each scene built once per session: this module's scenes, else those of ``hard_scenes``."""
    if scene in MAKERS:
        return vcigen.build(MAKERS[scene](), backend=backend, tol=tol)
    return simulator(scene, backend, tol=tol)


def _steps_after(res: vcigen.Result, t: float) -> np.ndarray:
    """Grid steps [t_k, t_k+1] that start at or after ``t``."""
    return res.t[:-1] >= t


# ------------------------------------------------------------------ a particle on a floor


@pytest.mark.parametrize("vy0", [0.0, 1e-6])
@pytest.mark.parametrize("backend", BACKENDS)
def test_sliding_particle_is_held_on_the_floor_by_mg_and_keeps_p_x(backend, vy0):
    """On the floor with v0 = (1, vy0): held there, x = t, p_x = 1 exactly (Noether, flat floor).

    The force is the weight m g; over the first step it also absorbs the start's normal
    momentum vy0 (a speed far below the jump's resolution g h): the impulse balance
    p_y(h) - p_y(0) = h (lambda_0 - g) with p_y(h) = 0 gives lambda_0 = g - vy0 / h.
    """
    h = 0.01
    res = sim("ball_elastic", backend).simulate([0.0, 0.0], [1.0, vy0], h, t_end=1.0)
    assert res.active[:, 0].all()
    assert res.n_impacts == 0
    assert np.abs(res.q[:, 1]).max() <= 1e-9
    assert np.all(res.p[:, 0] == 1.0)
    np.testing.assert_allclose(res.q[:, 0], res.t, rtol=0, atol=1e-12)
    np.testing.assert_allclose(res.p[1:, 1], 0.0, rtol=0, atol=1e-12)
    assert res.contact_force[0, 0] == pytest.approx(G - vy0 / h, abs=1e-9)
    np.testing.assert_allclose(res.contact_force[1:, 0], G, rtol=0, atol=1e-9)
    # E_d of a step on the floor is the sliding kinetic energy (the potential is 0 there)
    np.testing.assert_allclose(res.energy, 0.5, rtol=0, atol=1e-12)


@pytest.mark.parametrize("backend", BACKENDS)
def test_dropped_particle_lands_plastically_and_then_rests_with_force_mg(backend):
    """e = 0, dropped from y = 1 with vx = 0.5: one plastic impact at t1 = sqrt(2/g).

    The free flight is exact on the grid (trapezoid, constant gravity), so are the contact time
    and the incoming speed v1 = sqrt(2 g); the plastic law removes it (impulse v1, loss
    v1^2/2 = g), keeps p_x, and from then on the particle rests on the floor (y = 0, p_y = 0,
    force g, E_d = vx^2/2).
    """
    h, vx = 0.01, 0.5
    res = sim("ball", backend).simulate([0.0, 1.0], [vx, 0.0], h, t_end=1.0, params={"e": 0.0})
    t1, v1 = math.sqrt(2 / G), math.sqrt(2 * G)
    assert res.n_impacts == 1 and res.stats["impacts_plastic"] == 1
    (im,) = res.impacts
    assert im.kind == "plastic" and im.contact == "floor"
    assert im.t == pytest.approx(t1, abs=1e-12)
    assert im.impulse == pytest.approx(v1, rel=1e-12)
    # the E_d either side carry biases of at most g^2 h^2 / 8 (sub-steps of unequal length)
    assert im.energy_before - im.energy_after == pytest.approx(G, abs=G * G * h * h / 8)
    after = res.t > t1
    np.testing.assert_array_equal(res.active[:, 0], after)
    np.testing.assert_allclose(
        res.q[~after], parabola([0.0, 1.0], [vx, 0.0], res.t[~after]), rtol=0, atol=1e-12
    )
    assert np.abs(res.q[after, 1]).max() <= 1e-12
    np.testing.assert_allclose(res.p[after, 1], 0.0, rtol=0, atol=1e-12)
    rest = _steps_after(res, t1 + h)
    np.testing.assert_allclose(res.contact_force[rest, 0], G, rtol=0, atol=1e-9)
    np.testing.assert_allclose(res.energy[rest], vx**2 / 2, rtol=0, atol=1e-12)
    assert np.all(res.p[:, 0] == vx)
    np.testing.assert_allclose(res.q[:, 0], vx * res.t, rtol=0, atol=1e-12)
    assert not res.liftoffs


@pytest.mark.parametrize("backend", BACKENDS)
def test_sliding_particle_with_a_tiny_vertical_speed_does_not_pump(backend):
    """v0 = (1, 1e-6): the exact hop is v^2/(2 g) = 5e-14 high. No pumping of energy into hops.

    (The paper's jump alone pumps it: each impact at fraction alpha shifts the true energy by
    g^2 h^2 (1 - 2 alpha)/8, see the strict-mode test below.)
    """
    vy0 = 1e-6
    res = sim("ball_elastic", backend).simulate([0.0, 0.0], [1.0, vy0], 0.01, t_end=1.0)
    assert res.n_impacts <= 1
    assert res.q[:, 1].max() < 1e-9
    assert res.q[:, 1].min() >= -1e-9
    assert res.active[-1, 0]
    # the energy never rises above the start's (1 + vy0^2)/2, up to round-off
    assert res.energy.max() <= (1 + vy0**2) / 2 + 1e-12


@pytest.mark.parametrize("backend", BACKENDS)
def test_strict_grazing_error_mode_hops_on_the_floor_where_the_default_rests(backend):
    """At rest on the floor, v0 = (1, 0). Strict mode (the paper alone) must take elastic jumps.

    The first step crosses the floor at alpha -> 0; keeping E_d (bias -g^2 tau^2/8) over
    the unequal sub-steps gives the true vertical energy g^2 h^2/8: a hop of height g h^2/8.
    Every later impact shifts it by at most g^2 h^2/8 more, so the hops stay below
    n_impacts g h^2/8. The default mode rests instead: no impact, y = 0 exactly.
    """
    h = 0.01
    strict = sim("ball_elastic", backend, STRICT).simulate([0.0, 0.0], [1.0, 0.0], h, t_end=1.0)
    assert strict.n_impacts >= 10
    assert {im.kind for im in strict.impacts} == {"elastic"}
    assert max(abs(im.energy_after - im.energy_before) for im in strict.impacts) <= 1e-12
    hop = G * h * h / 8
    assert 0.9 * hop <= strict.q[:, 1].max() <= strict.n_impacts * hop
    assert strict.q[:, 1].min() >= -1e-9
    assert not strict.active.any()

    default = sim("ball_elastic", backend).simulate([0.0, 0.0], [1.0, 0.0], h, t_end=1.0)
    assert default.n_impacts == 0
    assert np.abs(default.q[:, 1]).max() <= 1e-12
    assert default.active.all()


# ------------------------------------------------------------------ grazing a ceiling


@pytest.mark.parametrize(("delta", "t_apex", "h"), GRAZING)
@pytest.mark.parametrize("backend", BACKENDS)
def test_grazing_the_ceiling_is_a_logged_reflection_by_default(backend, delta, t_apex, h):
    """Apex delta above the ceiling y = 1: normal speed vn = sqrt(2 g delta) ~ 4e-5 .. 4e-4 at contact.

    Gravity pulls away from the ceiling, so such an impact is touch and go: the continuous
    law n.qdot -> -n.qdot (kind "grazing"), or an elastic jump (E_d kept). Reflection: at the
    logged impact the velocity of the exact parabola is reversed (round-off), and the impact
    lies within round-off of the exact one (y near 1 is known to a few ulp = 1e-15: the time to
    1e-15/vn, the reflected speed to 2 g 1e-15/vn). Never a SolverError, never held.
    """
    vy = G * t_apex
    q0, v0 = [0.0, 1.0 + delta - vy**2 / (2 * G)], [1.0, vy]
    s = sim("ceiling", backend)
    res = s.simulate(q0=q0, v0=v0, h=h, t_end=1.0)  # no SolverError
    assert not res.active.any() and not res.liftoffs
    assert min_phi(s, res) >= -1e-9
    vn = math.sqrt(2 * G * delta)
    if res.n_impacts == 0:  # missed: only a dip shallower than the admissibility tolerance
        assert delta <= s.tol.admissible
        np.testing.assert_allclose(res.q, parabola(q0, v0, res.t), rtol=0, atol=1e-12)
        return
    assert res.n_impacts == 1
    (im,) = res.impacts
    assert im.kind in ("grazing", "elastic")
    t_exact = t_apex - vn / G
    round_off = 8 * np.finfo(float).eps  # a few ulp of y = 1
    assert abs(im.t - t_exact) <= round_off / vn
    after = res.t > im.t
    v_in = vy - G * im.t  # the parabola's vertical velocity at the logged impact
    if im.kind == "grazing":
        np.testing.assert_allclose(res.p[after, 1], -v_in - G * (res.t[after] - im.t), rtol=0, atol=1e-13)
        exact = vy - G * res.t[after] - 2 * vn  # the exact reflected parabola
        np.testing.assert_allclose(res.p[after, 1], exact, rtol=0, atol=2 * G * round_off / vn)
        assert abs(im.energy_after - im.energy_before) <= G * G * h * h / 8 * (1 + 1e-9)
        assert res.stats["impacts_grazing"] == 1
    else:
        assert abs(im.energy_after - im.energy_before) <= 1e-12 * abs(res.energy[0])
    np.testing.assert_array_equal(res.p[:, 0], 1.0)


# ------------------------------------------------------------------ a rod on two vertices


def _rod_release_speed(theta0: float) -> float:
    """|theta'| when a rod released at rest on one vertex, tilted theta0, lands flat (energy).

    Pivoting on the vertex y = l sin(theta) (x fixed): (l^2 cos^2 + I) w^2/2 = g l (sin theta0 - sin theta).
    """
    return math.sqrt(2 * G * ROD_L * math.sin(theta0) / (ROD_L**2 + ROD_I))


@pytest.mark.parametrize("backend", BACKENDS)
def test_rod_dropped_flat_rests_on_both_vertices_each_carrying_half_its_weight(backend):
    """Flat from y = 1, e = 0: both vertices land at t1 = sqrt(2/g), each takes half of m v1.

    Then the rod rests on both with lambda = m g / 2 each, theta = 0, p_x kept.
    """
    h, vx = 0.01, 0.3
    res = sim("rod", backend).simulate([0.0, 1.0, 0.0], [vx, 0.0, 0.0], h, t_end=1.0)
    t1, v1 = math.sqrt(2 / G), math.sqrt(2 * G)
    assert sorted(im.contact for im in res.impacts) == ["left", "right"]
    for im in res.impacts:
        assert im.kind == "plastic"
        assert im.t == pytest.approx(t1, abs=1e-12)
        assert im.impulse == pytest.approx(v1 / 2, rel=1e-12)
    after = res.t > t1
    assert res.active[after].all() and not res.active[~after].any()
    rest = _steps_after(res, t1 + h)
    np.testing.assert_allclose(res.contact_force[rest], G / 2, rtol=0, atol=1e-9)
    assert np.abs(res.q[after, 1]).max() <= 1e-12
    assert np.abs(res.q[:, 2]).max() <= 1e-12 and np.abs(res.p[:, 2]).max() <= 1e-12
    np.testing.assert_allclose(res.p[:, 0], vx, rtol=0, atol=1e-15)
    assert not res.liftoffs


@pytest.mark.parametrize("e", [0.0, 0.5])
@pytest.mark.parametrize("backend", BACKENDS)
def test_tilted_rod_hits_with_one_vertex_while_the_other_rests(backend, e):
    """Released at rest on its left vertex, tilted theta0 = 0.3: it pivots, the right vertex strikes.

    Newton's law on the two rows at theta = 0 (left held at normal speed 0, right leaving at
    -e times its incoming 2 l w): y' and theta' both reverse with factor e, the right impulse is
    (1 + e) w (l + I/l)/2 with w of :func:`_rod_release_speed`, and the kinetic energy at the
    strike, g l sin(theta0), drops by the factor e^2. Each later strike (e > 0) comes back with
    the speed it left with: impulses shrink by e. The left vertex stays held throughout, the rod
    ends flat on both, m g/2 each. Energy never rises at an impact.
    """
    h, th0 = 0.01, 0.3
    res = sim("rod", backend).simulate(
        [0.0, ROD_L * math.sin(th0), th0], [0.0, 0.0, 0.0], h, t_end=1.5, params={"e": e}
    )
    np.testing.assert_array_equal(res.active[0], [True, False])  # at rest on the left vertex
    assert res.n_impacts >= 1 and {im.contact for im in res.impacts} == {"right"}
    for im in res.impacts:  # every strike of the right vertex happens while the left one rests
        assert res.active[im.step, 0] and res.active[im.step + 1, 0]
    first = res.impacts[0]
    assert first.kind == ("plastic" if e == 0 else "restitution")
    w = _rod_release_speed(th0)
    # O(h^2): the pivot phase is second order (its strike time is within 0.01 h^2, next test)
    assert first.impulse == pytest.approx((1 + e) * w * (ROD_L + ROD_I / ROD_L) / 2, rel=h * h)
    kinetic = G * ROD_L * math.sin(th0)
    assert first.energy_before - first.energy_after == pytest.approx(
        (1 - e * e) * kinetic, abs=G * G * h * h / 8
    )
    impulses = np.array([im.impulse for im in res.impacts])
    if e > 0:
        assert res.n_impacts >= 3
        np.testing.assert_allclose(impulses[1:-1] / impulses[:-2], e, rtol=10 * h * h)
    assert res.impacts[-1].kind == "plastic"
    scale = abs(res.energy[0])
    for im in res.impacts:
        assert im.energy_after <= im.energy_before + 1e-9 * scale
    assert res.active[-1].all()
    np.testing.assert_allclose(res.contact_force[-1], G / 2, rtol=0, atol=1e-9)
    assert abs(res.q[-1, 2]) <= 1e-9 and abs(res.q[-1, 1]) <= 1e-9
    np.testing.assert_allclose(res.p[:, 0], 0.0, rtol=0, atol=1e-15)
    assert not res.liftoffs


@cache
def _rod_pivot_reference(theta0: float):
    """scipy on the pivot y = l sin(theta), x = 0: (l^2 cos^2 + I) th'' = l^2 cos sin th'^2 - g l cos.

    The vertex force is g + l (cos th'' - sin th'^2). Returns the time the rod lands flat
    (theta = 0) and that force as a function of t.
    """
    arm, inertia = ROD_L, ROD_I

    def accel(th, w):
        c, s = np.cos(th), np.sin(th)
        return (arm * arm * c * s * w * w - G * arm * c) / (arm * arm * c * c + inertia)

    def force(z):
        th, w = z
        return G + arm * (np.cos(th) * accel(th, w) - np.sin(th) * w * w)

    def flat(_t, z):
        return z[0]

    flat.terminal, flat.direction = True, -1
    sol = solve_ivp(
        lambda _t, z: [z[1], accel(*z)], (0.0, 2.0), [theta0, 0.0], method="DOP853",
        rtol=1e-12, atol=1e-12, events=flat, dense_output=True,
    )  # fmt: skip
    t_flat = float(sol.t_events[0][0])
    assert abs(sol.y_events[0][0][1]) == pytest.approx(_rod_release_speed(theta0), rel=1e-10)
    return t_flat, lambda t: force(sol.sol(t))


def _step_means(f, t_starts: np.ndarray, h: float) -> np.ndarray:
    """Means of ``f`` over the steps [t, t + h] (6-point Gauss-Legendre)."""
    x, w = np.polynomial.legendre.leggauss(6)
    return np.array([f(t + (x + 1) * h / 2) @ w / 2 for t in t_starts])


@pytest.mark.parametrize("backend", BACKENDS)
def test_tilted_rod_impact_time_converges_at_order_two(backend):
    """e = 0, released on the left vertex at theta0 = 0.3: the right vertex lands at t_flat (scipy).

    The strike time converges as h^2, and the left vertex's force, step by step, is the
    scipy normal force g + l (cos theta theta'' - sin theta theta'^2) to O(h^2) (positive, so
    no lift-off).
    """
    th0 = 0.3
    t_flat, force = _rod_pivot_reference(th0)
    hs, errs, idle = [0.01, 0.005, 0.0025], [], []
    for h in hs:
        res = sim("rod", backend).simulate(
            [0.0, ROD_L * math.sin(th0), th0], [0.0, 0.0, 0.0], h, t_end=0.3, params={"e": 0.0}
        )
        strike = [im for im in res.impacts if im.contact == "right"]
        assert len(strike) == 1 and strike[0].kind == "plastic"
        errs.append(abs(strike[0].t - t_flat))
        pivot = res.t[1:] <= t_flat  # steps wholly on the left vertex
        assert res.active[: pivot.sum() + 1, 0].all()
        exact = _step_means(force, res.t[:-1][pivot], h)
        assert exact.min() > 0
        np.testing.assert_allclose(res.contact_force[pivot, 0], exact, rtol=0, atol=3 * h * h)
        idle.append(np.abs(res.contact_force[pivot, 1]).max())
    order = fit_order(hs, errs)
    assert 1.8 < order < 2.2, (order, errs)
    assert max(err / h**2 for err, h in zip(errs, hs)) < 0.02, errs
    assert max(idle) == 0.0, idle  # API: the force is 0 where a contact is not in sustained contact


# ------------------------------------------------------------------ sliding into a wall


@pytest.mark.parametrize("h", [0.01, 0.0123])
@pytest.mark.parametrize("x0", [0.0, 0.0037])
@pytest.mark.parametrize("e", [0.0, 0.5, 1.0])
@pytest.mark.parametrize("backend", BACKENDS)
def test_sliding_particle_strikes_a_wall_while_held_on_the_floor(backend, e, x0, h):
    """Sliding at vx = 1 on the floor into the wall x = 1: one impact at t_w = 1 - x0 exactly.

    Newton's law with restitution e on the wall row, the floor row held: x = 1 - e (t - t_w)
    after, p_x = -e, impulse 1 + e, kinetic loss (1 - e^2)/2; the floor stays active with the
    weight as its force and p_y = 0 throughout; the wall is never held (nothing presses into it).
    At e = 0 the particle touches the wall and goes (it leaves at a normal speed of 0, nothing
    pressing it in): ``"grazing"``, as a free impact's touch and go is (MATH.md, *Entry*).
    """
    res = sim("floor_wall", backend).simulate([x0, 0.0], [1.0, 0.0], h, t_end=1.5, params={"e": e})
    t_w = 1.0 - x0
    assert res.n_impacts == 1
    (im,) = res.impacts
    assert im.contact == "wall" and im.kind == {1.0: "elastic", 0.5: "restitution", 0.0: "grazing"}[e]
    assert im.t == pytest.approx(t_w, abs=1e-12)
    assert im.impulse == pytest.approx(1 + e, abs=1e-12)
    assert im.energy_before - im.energy_after == pytest.approx((1 - e * e) / 2, abs=1e-12)
    after = res.t > t_w
    x_exact = np.where(after, 1.0 - e * (res.t - t_w), x0 + res.t)
    np.testing.assert_allclose(res.q[:, 0], x_exact, rtol=0, atol=1e-12)
    np.testing.assert_allclose(res.p[after, 0], -e, rtol=0, atol=1e-12)
    np.testing.assert_allclose(res.p[:, 1], 0.0, rtol=0, atol=1e-15)
    assert np.abs(res.q[:, 1]).max() <= 1e-12
    assert res.active[:, 0].all() and not res.active[:, 1].any()
    np.testing.assert_allclose(res.contact_force[:, 0], G, rtol=0, atol=1e-9)
    assert not res.liftoffs
    np.testing.assert_array_equal(res.contact_force[:, 1], 0.0)  # the wall is never held


# ------------------------------------------------------------------ a frictionless bowl


BOWL_V0 = 8.0  # from (1, 0) straight up: E = 32, pressed against the rim all the way round


def _bowl_force_error(res: vcigen.Result) -> float:
    """Largest |lambda - (E - 3 g y/2)| over the steps, y the step's mean height, E = v0^2/2."""
    y_mid = (res.q[1:, 1] + res.q[:-1, 1]) / 2
    return float(np.abs(res.contact_force[:, 0] - (BOWL_V0**2 / 2 - 1.5 * G * y_mid)).max())


@pytest.mark.slow
@pytest.mark.parametrize("backend", BACKENDS)
def test_sliding_round_a_frictionless_bowl_keeps_e_d_bounded_without_drift(backend):
    """Loops inside the unit circle (1e5 steps of h = 0.01 on C, 2e4 on CasADi): held all the way.

    With E = v0^2/2 = 32 the rim force lambda grad(phi) = -2 lambda q has lambda =
    (v^2 - g y)/2 = E - 3 g y/2 > 0 (17.3 at the top). Compared on every step at its mean
    height, the error is O(h^2) (4x from h = 0.02 to 0.01) with the constant a^2/8 of the
    discrete-energy bias, a = v^2/R <= 2 E + 2 g the centripetal acceleration. E_d oscillates
    with an O(h^2) amplitude (its peak to peak shrinks 4x too) and does not drift: the
    least-squares slope over the run adds up to less than 1% of the peak to peak (an O(h^2)
    drift, as of a non-symplectic method, would be ~1e-4 per unit time, more than the peak to
    peak over the run).
    """
    s = sim("bowl", backend)
    h, steps = 0.01, (100_000 if backend == "c" else 20_000)
    energy0 = BOWL_V0**2 / 2
    res = s.simulate([1.0, 0.0], [0.0, BOWL_V0], h, t_end=steps * h)
    assert res.n_impacts == 0 and not res.liftoffs
    assert res.active.all()
    assert np.abs(res.q[:, 0] ** 2 + res.q[:, 1] ** 2 - 1).max() <= 1e-9
    accel = 2 * energy0 + 2 * G  # the largest centripetal acceleration v^2/R (R = 1), at the bottom
    force_error = _bowl_force_error(res)
    assert force_error <= 1.1 * accel**2 * h * h / 8, force_error / h**2
    ptp = np.ptp(res.energy)
    assert abs(np.mean(res.energy) - energy0) <= ptp
    slope = np.polyfit(res.t[:-1], res.energy, 1)[0]  # least-squares drift per unit time
    assert abs(slope) * res.t[-1] <= 0.01 * ptp, (slope, ptp)
    coarse = s.simulate([1.0, 0.0], [0.0, BOWL_V0], 2 * h, t_end=2000 * 2 * h)
    assert coarse.active.all()
    assert np.ptp(coarse.energy) / ptp == pytest.approx(4.0, rel=0.1)
    assert _bowl_force_error(coarse) / force_error == pytest.approx(4.0, rel=0.1)


@pytest.mark.parametrize("y0", [0.0, 1e-10])
@pytest.mark.parametrize("backend", BACKENDS)
def test_released_at_rest_on_the_bowls_rim_it_swings_as_a_pendulum_through_a_right_angle(backend, y0):
    """Released at rest at the rim of the unit bowl, ``(1, y0)``: the wall is vertical there and gravity
    along it (``phi'' = 0``, not pressed in), but the free fall leaves the bowl at fourth order, so it is held
    from the start and slides as a pendulum of amplitude pi/2: at the bottom at ``T/4 = sqrt(r/g) K(1/2)``
    (``K`` of parameter ``m = 1/2``), past it again at ``3T/4`` after the other rim, never released, no
    impact; the times to O(h^2). Before stop 36 the start was not held and the free step crossed the wall at
    once, again and again: "more than 64 impacts in one step" at step 0 (CasADi at ``y0 = 0``, C at
    ``1e-10``, on ``r - |q|``)."""
    quarter = math.sqrt(1 / G) * float(ellipk(0.5))
    errs = []
    for h in (0.004, 0.002):
        res = sim("bowl", backend).simulate([1.0, y0], [0.0, 0.0], h, t_end=3 * quarter + 0.05)
        assert res.active[:, 0].all() and not res.impacts and not res.liftoffs
        x = res.q[:, 0]
        down = np.flatnonzero((x[:-1] > 0) & (x[1:] <= 0))[0]
        up = np.flatnonzero((x[:-1] < 0) & (x[1:] >= 0))[0]
        t_down = res.t[down] + h * x[down] / (x[down] - x[down + 1])
        t_up = res.t[up] - h * x[up] / (x[up + 1] - x[up])
        errs.append(max(abs(t_down - quarter), abs(t_up - 3 * quarter)))
    assert errs[0] < 5e-5 and errs[0] / errs[1] == pytest.approx(4.0, rel=0.05), errs


@pytest.mark.parametrize("backend", BACKENDS)
def test_a_pendulum_started_at_rest_against_its_wall_rests_there_with_the_static_force(backend):
    """The bob at rest on the wall ``x = 0.3`` beside its bottom: only the rod's reaction presses it in (the
    free acceleration is vertical, along the wall). Held from the start, it stays, the wall pushing with the
    statics' ``g tan(theta)``, ``sin(theta) = 0.3``, and ``E_d`` constant. Before stop 36 the start judged
    the wall by the free acceleration alone (not pressed in): the first step crossed it and logged 1 (C) or
    4 (CasADi) restitution impacts of ~1e-8 and a plastic one, ``E_d[0]`` 1.4e-4 below the rest."""
    q0 = [0.3, -math.sqrt(1 - 0.09)]
    res = sim("rod_wall", backend).simulate(q0, [0.0, 0.0], 0.01, t_end=1.0)
    assert not res.impacts and not res.liftoffs and res.active[:, 0].all()
    assert np.abs(res.q - q0).max() < 1e-12
    np.testing.assert_allclose(res.contact_force[:, 0], G * 0.3 / math.sqrt(0.91), rtol=0, atol=1e-9)
    assert np.ptp(res.energy) < 1e-12


@pytest.mark.parametrize("backend", BACKENDS)
def test_a_start_on_the_bowl_moving_away_from_it_flies_free_where_its_path_does_not_come_back(backend):
    """On the unit bowl at 45 degrees, sliding up along it at ``v^2 = g sin(45) + 0.09`` (the wall presses
    with 0.09 per unit mass, falling to 0 within 1.6 ms) and moving off it at 7e-4: below the jump's
    resolution (``|phi'| <= h |phi''|``), but the free path does not come back within the step. The
    exact motion is free flight from the start: the grid points are the parabola's, no lift-off, no
    force, until the particle hits the bowl across (t = 0.759). Before stop 37 the start was held: its
    first step pulled the particle back (mean force -0.031, a lift-off at 1.6 ms; a fuzzed ellipse's
    -0.086), 3.3e-4 off the parabola."""
    a = math.pi / 4
    q0, along = np.array([math.cos(a), math.sin(a)]), np.array([-math.sin(a), math.cos(a)])
    v0 = math.sqrt(G * math.sin(a) + 0.09) * along - 7e-4 * q0  # up along the bowl, off it inwards
    res = sim("bowl", backend).simulate(q0.tolist(), v0.tolist(), 0.01, t_end=1.0)
    assert res.impacts and not res.liftoffs and not res.active[:, 0].any()
    assert np.all(res.contact_force == 0.0)
    before = res.t < res.impacts[0].t
    assert before.sum() > 10
    np.testing.assert_allclose(res.q[before], parabola(q0, v0, res.t[before]), rtol=0, atol=1e-12)


@pytest.mark.parametrize("backend", BACKENDS)
def test_a_pendulum_swung_across_the_corner_of_its_rod_and_a_wall_stops_there(backend):
    """The bob on its rod swung down into the wall ``x = -0.99``, which cuts the circle's arc of 0.28 rad
    about ``(-1, 0)``: at ``h = 0.1`` a held step (only the rod held) ended past the corner, on the wall's
    side again (``x >= -0.99``), so its end's test saw nothing and the bob passed through the wall,
    silently (from the corner at 3 m/s, both backends; from 0.1 rad above at 0.5 m/s on CasADi; C raised
    there). A held step whose inactive row ends within its reach is left to the chain
    (``held_step.idle_near``), which tests the row for a dip as free flight does (``_row_dips``): the bob
    meets the wall when the pendulum does (scipy, event located, 1e-12), to second order, and stops in the
    corner (``e = 0``: its only motions there are away from the wall)."""
    from scipy.integrate import solve_ivp

    d = 0.99
    corner = math.atan2(math.sqrt(1 - d**2), -d)
    a = corner - 0.1  # 0.1 rad above the corner, swinging down into it at 0.5 m/s
    hit = lambda t, y: math.cos(y[0]) + d  # noqa: E731
    hit.terminal = True
    exact = solve_ivp(
        lambda t, y: [y[1], -G * math.cos(y[0])], (0, 2), [a, 0.5], events=hit, rtol=1e-12, atol=1e-12
    )
    starts = {  # from above, and from the corner itself at 3 m/s
        "above": ([math.cos(a), math.sin(a)], [-0.5 * math.sin(a), 0.5 * math.cos(a)]),
        "corner": ([-d, math.sqrt(1 - d**2)], [-3 * math.sqrt(1 - d**2), -3 * d]),
    }
    errors = []
    for name, (q0, v0) in starts.items():
        for h in (0.1, 0.05) if name == "above" else (0.1,):
            res = sim("rod_wall", backend).simulate(q0, v0, h, t_end=0.5, params={"a": -d, "e": 0.0})
            assert res.impacts and (res.q[:, 0] + d).min() > -1e-12
            assert res.q[:, 1].min() >= math.sqrt(1 - d**2) - 1e-12  # never past the corner
            assert (
                np.abs(res.q[-1] - [-d, math.sqrt(1 - d**2)]).max() < 1e-12
                and np.abs(res.v[-1]).max() < 1e-12
            )
            assert res.active[-1, 0]
            if name == "above":
                errors.append(abs(res.impacts[0].t - exact.t_events[0][0]))
            else:
                assert res.impacts[0].t < 1e-12  # at the start (located to the root finder's 1e-14)
    assert errors[0] < 1e-4 and errors[0] / errors[1] > 3.5  # at least second order


@pytest.mark.parametrize("backend", BACKENDS)
def test_a_pendulum_swung_into_the_narrow_corner_of_its_rod_and_a_wall_stays_in_it(backend):
    """The wall ``x = -0.999`` meets the rod's circle 2.6 degrees from the rod's direction: held on both rows
    (``e = 0``), the bob is pinned, and the two rows also meet at the mirror corner below, 0.089 away. At ``h
    = 0.1`` the segment after the plastic impact started its Newton from the velocity before it (1.35 m/s
    down the wall) and took that corner, with a wall pulling at -14.5: CasADi's bob went on below, through
    the wall, silently (from 0.1 rad above at 0.3 m/s); C raised "sustained solve failed" (0.2, 0.3 and
    0.5 m/s). The chain now starts from the velocity after an impact (0 here): the bob meets the wall when
    the pendulum does (scipy, event located, 1e-12) and stays in the corner."""
    d = 0.999
    yc = math.sqrt(1 - d**2)
    a = math.atan2(yc, -d) - 0.1
    hit = lambda t, y: math.cos(y[0]) + d  # noqa: E731
    hit.terminal = True
    for speed in (0.2, 0.3, 0.5):
        exact = solve_ivp(
            lambda t, y: [y[1], -G * math.cos(y[0])], (0, 2), [a, speed], events=hit, rtol=1e-12, atol=1e-12
        ).t_events[0][0]
        q0, v0 = [math.cos(a), math.sin(a)], [-speed * math.sin(a), speed * math.cos(a)]
        res = sim("rod_wall", backend).simulate(q0, v0, 0.1, t_end=1.0, params={"a": -d, "e": 0.0})
        assert abs(res.impacts[0].t - exact) < 1e-4
        assert (res.q[:, 0] + d).min() > -1e-12 and res.q[:, 1].min() > yc - 1e-11  # never past the corner
        assert np.abs(res.q[-1] - [-d, yc]).max() < 1e-11 and np.abs(res.v[-1]).max() < 1e-12
        assert res.active[-1, 0]


@pytest.mark.parametrize("backend", BACKENDS)
def test_a_held_step_that_moves_the_bob_farther_than_its_rod_has_no_root_and_says_so(backend):
    """RATTLE on the unit rod: ``|q + tau (p + 2 Lam q)|^2 = (1 + 2 tau Lam)^2 + tau^2 |p|^2`` is 1 only where
    ``tau |p| <= 1``. At the bottom at 9.5 m/s and ``h = 0.1`` the pendulum runs (its rod kept); at 10.5 m/s
    the first held step has no root, and the error says why (``errors.HELD_NO_ROOT``), not only "reduce h",
    and names the row held (``errors.HELD_ROWS``; since stop 43)."""
    s = sim("rod_wall", backend)
    res = s.simulate([0.0, -1.0], [9.5, 0.0], 0.1, t_end=1.0, params={"a": -5.0})
    assert np.abs(res.q[:, 0] ** 2 + res.q[:, 1] ** 2 - 1).max() < 1e-12
    with pytest.raises(vcigen.SolverError, match="sustained solve failed") as err:
        s.simulate([0.0, -1.0], [10.5, 0.0], 0.1, t_end=1.0, params={"a": -5.0})
    assert err.value.step == 0
    assert str(err.value).endswith(vcigen.errors.HELD_NO_ROOT + vcigen.errors.HELD_ROWS + "rod")


@pytest.mark.parametrize("h", [0.1, 0.05])
@pytest.mark.parametrize("backend", BACKENDS)
def test_a_pendulum_at_rest_in_the_corner_of_its_rod_and_a_wall_stays_with_the_static_forces(backend, h):
    """The bob at rest on the wall ``x = -0.999`` just above the pivot (``y = sqrt(1 - 0.999^2)``): gravity
    pulls it down the circle into the wall, 2.6 degrees from the rod's direction, and the statics give the
    wall's force ``g |x| / y`` = 219 (the rod pushing). Held from the start, its first step's Newton starts
    from the forces that hold it (``_start_sustained``). Before stop 37 it started from 0, and C's Newton did
    not converge at ``h = 0.1`` ("sustained solve failed" at step 0); CasADi's did."""
    y0 = math.sqrt(1 - 0.999**2)
    res = sim("rod_wall", backend).simulate([-0.999, y0], [0.0, 0.0], h, t_end=1.0, params={"a": -0.999})
    assert not res.impacts and not res.liftoffs and res.active[:, 0].all()
    assert np.abs(res.q - [-0.999, y0]).max() < 1e-11
    np.testing.assert_allclose(res.contact_force[:, 0], G * 0.999 / y0, rtol=1e-9, atol=0)
    assert np.ptp(res.energy) < 1e-10
