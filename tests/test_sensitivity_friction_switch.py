"""Exact sensitivities through a friction switch inside a held step (MATH.md *Friction*, *Exact
sensitivities*; ``vcigen/sensitivity_switch.py``, ``templates/sens_switch.c.j2``).

A one-tangent contact that slips and comes to rest inside a step (``"stop"``, slip -> stick) or sticks until
its force reaches the cone (``"slide"``, stick -> slip) is a located event: a small change of the data keeps
the mode sequence and moves the event time smoothly, so the end state is differentiable. The tangent goes
through it: the event's fraction by the implicit-function theorem on its root, then the rest of the step in
the new mode.

Checked against closed forms (a block launched on a level floor and on an incline below the friction angle
stops at ``x0 + v0^2 / (2 D)``, ``D = g (mu cos a - sin a)``, at ``t* = v0 / D``; a disk sliding down an
incline until it rolls, differentiated symbolically), against central differences of whole runs (relative to
the largest entry), C against CasADi, on the trapezoidal and midpoint rules. What stays a break is reported on
both backends."""

from __future__ import annotations

import math
from functools import cache

import hard_scenes
import numpy as np
import pytest
import sympy as sp
from hard_scenes import G

import vcigen

BACKENDS = [hard_scenes.backend_param("casadi"), hard_scenes.backend_param("c")]
RULES = ["trapezoid", "midpoint"]
MU, V0 = 0.5, 2.0
FD_TOL = 1e-6  # the tangent against central differences, relative to the largest entry
C_TOL = 1e-9  # C against CasADi, relative
EPS = 1e-6
needs_c = pytest.mark.skipif(
    hard_scenes.c_backend_problem() is not None, reason=str(hard_scenes.c_backend_problem())
)


def block() -> vcigen.Model:
    """A block on a rough incline of angle ``a`` (``q = (x, y)`` along it, downhill ``+x``, and normal to
    it)."""
    x, y, xd, yd = sp.symbols("x y xd yd")
    m, g, mu, a = sp.symbols("m g mu a")
    return vcigen.Model(
        name="switch_block",
        q=[x, y],
        qdot=[xd, yd],
        lagrangian=m / 2 * (xd**2 + yd**2) - m * g * (y * sp.cos(a) - x * sp.sin(a)),
        contacts={"floor": y},
        params={m: 1.0, g: G, mu: MU, a: 0.0},
        friction={"floor": (mu, x)},
    )


def spring_disk() -> vcigen.Model:
    """A disk rolling on a rough level floor, tied to ``x = 0`` by a spring: it sticks (rolls) until the
    spring's pull needs more friction than the cone has (slide), slips, and rolls again when its sliding stops
    (stop)."""
    x, y, th, xd, yd, thd = sp.symbols("x y th xd yd thd")
    m, inertia, r, g, mu, k = sp.symbols("m I r g mu k")
    return vcigen.Model(
        name="switch_spring_disk",
        q=[x, y, th],
        qdot=[xd, yd, thd],
        lagrangian=m / 2 * (xd**2 + yd**2) + inertia / 2 * thd**2 - m * g * y - k / 2 * x**2,
        contacts={"floor": y - r},
        params={m: 1.0, inertia: 0.5, r: 1.0, g: G, mu: 0.2, k: 10.0},
        friction={"floor": (mu, x - r * th)},
    )


@cache
def sim(name: str, backend: str, rule: str) -> vcigen.Simulator:
    import test_sensitivity_friction

    make = {"block": block, "spring_disk": spring_disk, "disk": test_sensitivity_friction.incline_disk}[name]
    return vcigen.build(make(), backend=backend, rule=rule)


def run(name, backend, rule, q0, v0, h, t_end, params=None, sens=True) -> vcigen.Result:
    return sim(name, backend, rule).simulate(
        q0, v0, h, t_end=t_end, params=params, sensitivities=sens, progress=False
    )


def fd_error(name, backend, rule, q0, v0, h, t_end, params, columns) -> tuple[vcigen.Result, dict]:
    """The run's tangent against central differences of whole runs along each column in ``columns`` (indices
    into ``z = (q0, v0, params)``): each column's worst entry over every grid point, relative to the largest
    entry of the tangent on those columns."""
    s = sim(name, backend, rule)
    names = [str(p) for p in s.model.defaults]
    values = dict(zip(names, s.model.resolve_params(params)))
    res = run(name, backend, rule, q0, v0, h, t_end, values)
    assert res.sensitivity_breaks == [] and np.isfinite(res.sensitivity).all()
    n = len(q0)
    errs, scale = {}, 0.0
    for c in columns:
        ends = []
        for sign in (1.0, -1.0):
            z, par = np.array([*q0, *v0], dtype=float), dict(values)
            if c < 2 * n:
                z[c] += sign * EPS
            else:
                par[names[c - 2 * n]] += sign * EPS
            r = run(name, backend, rule, z[:n], z[n:], h, t_end, par, sens=False)
            assert np.array_equal(r.active, res.active) and len(r.impacts) == len(res.impacts)
            ends.append(np.hstack([r.q, r.p]))
        fd = (ends[0] - ends[1]) / (2 * EPS)
        errs[res.sensitivity_names[c]] = float(np.abs(res.sensitivity[:, :, c] - fd).max())
        scale = max(scale, float(np.abs(res.sensitivity[:, :, c]).max()))
    return res, {k: v / scale for k, v in errs.items()}


# -- a block that stops: the closed form ---------------------------------------------------------------------
def stop_closed_form(t: np.ndarray, a: float) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """Launched downhill at ``V0`` from ``x0 = 0``: ``x = V0 t - D t^2/2`` until ``t* = V0/D``, then
    ``V0^2/(2D)``; ``p = m (V0 - D t)``, then 0. Each column as ``(dx, dp)`` (``m = 1``), ``D = g (mu cos a -
    sin a)``."""
    d = G * (MU * math.cos(a) - math.sin(a))
    d_mu, d_g, d_a = G * math.cos(a), d / G, -G * (MU * math.sin(a) + math.cos(a))  # dD/d(mu, g, a)
    before = t < V0 / d
    half = t**2 / 2
    stop = V0**2 / (2 * d * d)  # -dx_end/dD

    def col(slip_x, rest_x, slip_p):
        return np.where(before, slip_x, rest_x), np.where(before, slip_p, 0.0)

    return {
        "x": (np.where(before, V0 * t - d * half, V0**2 / (2 * d)), np.where(before, V0 - d * t, 0.0)),
        "q0[x]": col(np.ones_like(t), 1.0, 0.0),
        "v0[x]": col(t, V0 / d, 1.0),
        "mu": col(-d_mu * half, -stop * d_mu, -d_mu * t),
        "g": col(-d_g * half, -stop * d_g, -d_g * t),
        "a": col(-d_a * half, -stop * d_a, -d_a * t),
        "m": col(0 * t, 0.0, V0 - d * t),
    }


def assert_tangent_is(res: vcigen.Result, want: dict) -> None:
    """Each column of ``want`` (:func:`stop_closed_form`'s, ``x`` aside) in the tangent's ``x`` and ``p_x``
    rows at every grid point, to 1e-10."""
    S = res.sensitivity
    col = {name: i for i, name in enumerate(res.sensitivity_names)}
    for name, (dx, dp) in want.items():
        if name != "x":
            assert np.allclose(S[:, 0, col[name]], dx, atol=1e-10, rtol=0), name
            assert np.allclose(S[:, 2, col[name]], dp, atol=1e-10, rtol=0), name


@pytest.mark.parametrize("h", [0.01, 0.023, 0.005])
@pytest.mark.parametrize("a", [0.0, 0.25])
@pytest.mark.parametrize("rule", RULES)
@pytest.mark.parametrize("backend", BACKENDS)
def test_stop_is_the_closed_form(backend: str, rule: str, a: float, h: float) -> None:
    """A block launched at V0 on the level floor or downhill on an incline below the friction angle (tan 0.25
    < mu) stops inside a step and sticks: d x_end/d v0 = v0/D, d x_end/d mu = -v0^2 g cos a/(2 D^2), ... at
    every grid point (before the stop: the sliding closed form), p and its tangent 0 after it; no break."""
    t_stop = V0 / (G * (MU * math.cos(a) - math.sin(a)))
    res = run("block", backend, rule, [0.0, 0.0], [V0, 0.0], h, 1.5 * t_stop, {"a": a})
    assert res.sensitivity_breaks == [] and res.active[:, 0].all()
    assert 0.0 < t_stop / h % 1.0 < 1.0  # the stop is inside a step
    want = stop_closed_form(res.t, a)
    assert np.allclose(res.q[:, 0], want["x"][0], atol=1e-12, rtol=0)
    assert np.allclose(res.p[:, 0], want["x"][1], atol=1e-12, rtol=0)
    assert_tangent_is(res, want)
    assert np.abs(res.sensitivity[1:, [1, 3]]).max() <= 1e-12  # held on the floor: y and p_y do not move


@pytest.mark.parametrize("steps", [20, 41])
@pytest.mark.parametrize("a", [0.0, 0.25])
@pytest.mark.parametrize("rule", RULES)
@pytest.mark.parametrize("backend", BACKENDS)
def test_stop_on_a_grid_point_is_the_closed_form(backend: str, rule: str, a: float, steps: int) -> None:
    """The stop on a grid point (``h = t_stop / steps``): the sliding at that step's end is round-off's. It is
    located at the step's end (``SLIDE_EPS``) and the tangent goes on through it (``Tracker.rest_end``: the
    event point's tangents moved along the stick by the tangent of the empty rest's length), the closed form
    at every grid point; at the stop's own, the stick's side (``p``'s tangent 0: the map has a kink there).
    Before stop 63 it broke there, ``"friction switch in a held step"``, on both backends."""
    t_stop = V0 / (G * (MU * math.cos(a) - math.sin(a)))
    h = t_stop / steps
    res = run("block", backend, rule, [0.0, 0.0], [V0, 0.0], h, 1.5 * t_stop, {"a": a})
    assert res.sensitivity_breaks == [] and np.isfinite(res.sensitivity).all()
    assert abs(res.t[steps] - t_stop) < 1e-12 * t_stop
    t = res.t.copy()
    t[steps] = t_stop * (1.0 + 1e-12)  # the stick's side
    want = stop_closed_form(t, a)
    assert np.allclose(res.q[:, 0], want["x"][0], atol=1e-12, rtol=0)
    assert np.abs(res.p[steps:, 0]).max() <= 1e-12
    assert_tangent_is(res, want)


@pytest.mark.parametrize("rule", RULES)
@pytest.mark.parametrize("backend", BACKENDS)
def test_stop_matches_finite_differences(backend: str, rule: str) -> None:
    """The block on the incline through its stop: every column that keeps the mode sequence (all but the
    normal ones, whose change lifts or presses the block) against central differences of whole runs."""
    res, errs = fd_error(
        "block", backend, rule, [0.0, 0.0], [V0, 0.0], 0.01, 1.0, {"a": 0.25}, [0, 2, 4, 5, 6, 7]
    )
    print(
        f"block stopping on the incline ({backend}, {rule}): FD worst "
        f"{max(errs, key=errs.get)} {max(errs.values()):.1e}"
    )
    assert max(errs.values()) <= FD_TOL, errs


# -- a disk that slides until it rolls -----------------------------------------------------------------------
def disk_closed_form(t_end: float):
    """The disk of test_sensitivity_friction (q = (x, y, theta), r, m, I, g, mu, a parameters) sliding down
    the incline from ``(x0, theta0)`` at ``(v0, w0)``, sliding velocity ``v0 - r w0 < 0``: slipping with ``x''
    = (mu cos a - sin a) g``, ``theta'' = -mu m g cos a r / I`` until the sliding stops at ``t*``, then
    rolling with ``x'' = -g sin a / (1 + I/(m r^2))``: ``x(t_end)`` as a SymPy expression and its symbols."""
    x0, th0, v0, w0, m, inertia, r, g, mu, a = sp.symbols("x0 th0 v0 w0 m I r g mu a")
    acc = (mu * sp.cos(a) - sp.sin(a)) * g
    alpha = -mu * m * g * sp.cos(a) * r / inertia
    t_star = -(v0 - r * w0) / (acc - r * alpha)
    x_star = x0 + v0 * t_star + acc * t_star**2 / 2
    v_star = v0 + acc * t_star
    rest = t_end - t_star
    x_end = x_star + v_star * rest - g * sp.sin(a) / (1 + inertia / (m * r * r)) * rest**2 / 2
    return x_end, (x0, th0, v0, w0, m, inertia, r, g, mu, a)


@pytest.mark.parametrize("rule", RULES)
@pytest.mark.parametrize("backend", BACKENDS)
def test_disk_rolls_after_a_stop_closed_form(backend: str, rule: str) -> None:
    """The disk sliding down the incline until it rolls (the slip -> stick of test_sensitivity_friction,
    formerly a break): x(T) and its columns in x0, v0, w0, m, I, g, mu, a against the symbolic derivative of
    the closed form through the stop time t*."""
    import test_sensitivity_friction as tsf

    T = 0.5
    v0 = [-1.0, 0.0, 0.0]
    res = run("disk", backend, rule, [0.0, tsf.PARAMS["r"], 0.0], v0, tsf.H, T, dict(tsf.PARAMS))
    assert res.sensitivity_breaks == [] and np.isfinite(res.sensitivity).all()
    x_end, syms = disk_closed_form(T)
    values = dict(
        zip(syms, [0.0, 0.0, v0[0], v0[2], *(tsf.PARAMS[k] for k in ("m", "I", "r", "g", "mu", "a"))])
    )
    assert abs(res.q[-1, 0] - float(x_end.subs(values))) <= 1e-12
    col = {name: i for i, name in enumerate(res.sensitivity_names)}
    pairs = {"q0[x]": 0, "v0[x]": 2, "v0[th]": 3, "m": 4, "I": 5, "g": 7, "mu": 8, "a": 9}
    for name, i in pairs.items():
        want = float(sp.diff(x_end, syms[i]).subs(values))
        assert abs(res.sensitivity[-1, 0, col[name]] - want) <= 1e-10, (
            name,
            res.sensitivity[-1, 0, col[name]],
            want,
        )


@pytest.mark.parametrize("rule", RULES)
@pytest.mark.parametrize("backend", BACKENDS)
def test_disk_stop_matches_finite_differences(backend: str, rule: str) -> None:
    """The same disk: every column that keeps the mode sequence against central differences."""
    import test_sensitivity_friction as tsf

    cols = [0, 2, 3, 5, 6, 7, 9, 10, 11]  # x0, th0, vx0, w0, m, I, g, mu, a
    res, errs = fd_error(
        "disk", backend, rule, [0.0, 1.0, 0.0], [-1.0, 0.0, 0.0], tsf.H, 0.5, tsf.PARAMS, cols
    )
    print(
        f"disk rolling after its stop ({backend}, {rule}): FD worst "
        f"{max(errs, key=errs.get)} {max(errs.values()):.1e}"
    )
    assert max(errs.values()) <= FD_TOL, errs


# -- stick -> slip -> stick: a disk on a spring --------------------------------------------------------------
def sliding(res: vcigen.Result) -> np.ndarray:
    """The spring disk's sliding velocity ``xd - r thetad`` at each grid point (m = 1, I = 0.5, r = 1)."""
    return res.p[:, 0] - res.p[:, 2] / 0.5


@pytest.mark.parametrize("rule", RULES)
@pytest.mark.parametrize("backend", BACKENDS)
def test_slide_then_stop_matches_finite_differences(backend: str, rule: str) -> None:
    """The spring disk rolls, slides when the spring's pull leaves the cone (stick -> slip inside a step),
    then rolls again when its sliding stops (slip -> stick): both switches carried, every column that keeps
    the mode sequence against central differences."""
    cols = [0, 2, 3, 5, 6, 7, 9, 10, 11]  # x0, th0, vx0, w0, m, I, g, mu, k
    res, errs = fd_error(
        "spring_disk", backend, rule, [0.0, 1.0, 0.0], [2.0, 0.0, 2.0], 0.01, 1.3, None, cols
    )
    stuck = np.abs(sliding(res)) <= 1e-9
    changes = np.flatnonzero(stuck[1:] != stuck[:-1]) + 1
    assert stuck[0] and len(changes) == 2 and not stuck[changes[0]] and stuck[changes[1]]  # roll, slide, roll
    print(
        f"spring disk, slide then stop ({backend}, {rule}): FD worst "
        f"{max(errs, key=errs.get)} {max(errs.values()):.1e}"
    )
    assert max(errs.values()) <= FD_TOL, errs


# -- C against CasADi ----------------------------------------------------------------------------------------
@needs_c
@pytest.mark.parametrize("rule", RULES)
def test_c_equals_casadi(rule: str) -> None:
    """Each scene through its switches: the C tangent (sens_switch.c.j2) against the CasADi one; the block
    also with its stop on grid point 20 (at a step's end: sens_ev_rest_end against Tracker.rest_end)."""
    on_grid = V0 / (G * (MU * math.cos(0.25) - math.sin(0.25))) / 20
    scenes = [
        ("block", [0.0, 0.0], [V0, 0.0], 0.01, 1.0, {"a": 0.25}),
        ("block", [0.0, 0.0], [V0, 0.0], on_grid, 1.0, {"a": 0.25}),
        ("disk", [0.0, 1.0, 0.0], [-1.0, 0.0, 0.0], 0.01, 0.5, None),
        ("spring_disk", [0.0, 1.0, 0.0], [2.0, 0.0, 2.0], 0.01, 3.0, None),  # 5 switches
    ]
    for name, q0, v0, h, t_end, par in scenes:
        a, b = (run(name, backend, rule, q0, v0, h, t_end, par) for backend in ("casadi", "c"))
        rel = float(np.abs(a.sensitivity - b.sensitivity).max() / np.abs(a.sensitivity).max())
        print(f"{name} ({rule}): C against CasADi {rel:.1e}")
        assert a.sensitivity_breaks == b.sensitivity_breaks == [] and rel <= C_TOL


# -- a stop, then at once a slide back -----------------------------------------------------------------------
@pytest.mark.parametrize("rule", RULES)
@pytest.mark.parametrize("backend", BACKENDS)
def test_stop_then_slide_back_is_the_closed_form(backend: str, rule: str) -> None:
    """Launched uphill at V0 on an incline steeper than the friction angle (tan 0.6 > mu): the block
    decelerates at D1 = g (sin a + mu cos a), stops at t* = V0/D1 inside a step, x* = -V0^2/(2 D1), and its
    stick force is at once outside the cone: it slides back at the same instant (a slide at the start of the
    rest of the step, its time the stop's: SustainedSteps._sw_back) with x'' = D2 = g (sin a - mu cos a). x(T)
    = x* + D2 (T - t*)^2/2, p(T) = D2 (T - t*): their columns in v0, mu, g, a against the symbolic
    derivatives; no break."""
    v0_, mu, g, a = sp.symbols("v0 mu g a")
    d1, d2 = g * (sp.sin(a) + mu * sp.cos(a)), g * (sp.sin(a) - mu * sp.cos(a))
    t_star = v0_ / d1
    T = 0.7
    x_end = -(v0_**2) / (2 * d1) + d2 * (T - t_star) ** 2 / 2
    p_end = d2 * (T - t_star)
    values = {v0_: V0, mu: MU, g: G, a: 0.6}
    res = run("block", backend, rule, [0.0, 0.0], [-V0, 0.0], 0.01, T, {"a": 0.6})
    assert res.sensitivity_breaks == [] and np.isfinite(res.sensitivity).all()
    assert abs(res.q[-1, 0] - float(x_end.subs(values))) <= 1e-12
    assert abs(res.p[-1, 0] - float(p_end.subs(values))) <= 1e-12
    col = {name: i for i, name in enumerate(res.sensitivity_names)}
    for name, sym, sign in (("v0[x]", v0_, -1.0), ("mu", mu, 1.0), ("g", g, 1.0), ("a", a, 1.0)):
        for row, expr in ((0, x_end), (2, p_end)):
            want = sign * float(sp.diff(expr, sym).subs(values))  # v0[x] = -v0
            assert abs(res.sensitivity[-1, row, col[name]] - want) <= 1e-10, (name, row, want)


# -- stick -> slip under a force of time ---------------------------------------------------------------------
@pytest.mark.parametrize("rule", RULES)
@pytest.mark.parametrize("backend", BACKENDS)
def test_slide_under_a_rising_push_matches_finite_differences(backend: str, rule: str) -> None:
    """test_friction's block pushed by F t on a level floor sticks until F t* = mu g, then slides (the stick
    force reaches the cone inside a step; the force law and the root move with the time slot): every column
    that keeps the mode sequence against central differences."""
    import test_friction

    s = vcigen.build(test_friction.block(), backend=backend, rule=rule)
    par = {"F": 3.0}
    names = [str(p) for p in s.model.defaults]
    values = dict(zip(names, s.model.resolve_params(par)))
    res = s.simulate([0.0, 0.0], [0.0, 0.0], 0.01, t_end=1.6, params=par, sensitivities=True, progress=False)
    assert res.sensitivity_breaks == [] and np.isfinite(res.sensitivity).all()
    assert res.q[-1, 0] > 0.01 and abs(res.q[130, 0]) < 1e-15  # stuck to t* = 1.308, sliding after
    errs, scale = {}, 0.0
    for c in (0, 4, 5, 7):  # x0, g, mu, F (v0 = 0 is the stick-slip boundary: left out)
        ends = []
        for sign in (1.0, -1.0):
            z, p = np.zeros(4), dict(values)
            if c < 4:
                z[c] += sign * EPS
            else:
                p[names[c - 4]] += sign * EPS
            r = s.simulate(z[:2], z[2:], 0.01, t_end=1.6, params=p, progress=False)
            ends.append(np.hstack([r.q, r.p]))
        fd = (ends[0] - ends[1]) / (2 * EPS)
        errs[res.sensitivity_names[c]] = float(np.abs(res.sensitivity[:, :, c] - fd).max())
        scale = max(scale, float(np.abs(res.sensitivity[:, :, c]).max()))
    errs = {k: v / scale for k, v in errs.items()}
    print(f"block under F t ({backend}, {rule}): FD worst {max(errs, key=errs.get)} {max(errs.values()):.1e}")
    assert max(errs.values()) <= FD_TOL, errs
    if backend == "c":
        a = vcigen.build(test_friction.block(), backend="casadi", rule=rule).simulate(
            [0.0, 0.0], [0.0, 0.0], 0.01, t_end=1.6, params=par, sensitivities=True, progress=False
        )
        rel = float(np.abs(a.sensitivity - res.sensitivity).max() / np.abs(a.sensitivity).max())
        print(f"block under F t ({rule}): C against CasADi {rel:.1e}")
        assert rel <= C_TOL


# -- what stays a break --------------------------------------------------------------------------------------
@pytest.mark.parametrize("backend", BACKENDS)
def test_two_ends_stopping_is_a_break(backend: str) -> None:
    """test_friction_rod's rod set down sliding on both ends stops at t = v/(mu g) on both at once: the first
    end sticks on its own row, the second becomes a dependent stick (statically indeterminate): not covered, a
    break with its reason at the stop's step, the same on both backends."""
    import test_friction_rod as tfr

    v = 1.0
    s = vcigen.build(tfr.rod(), backend=backend)
    res = s.simulate([0.0, 0.0, 0.0], [v, 0.0, 0.0], 0.01, t_end=0.5, sensitivities=True, progress=False)
    k = int(v / (tfr.MU * G) / 0.01)
    assert res.sensitivity_breaks == [(k, "friction switch in a held step")]
    assert np.isfinite(res.sensitivity[: k + 1]).all() and np.isnan(res.sensitivity[k + 1 :]).all()


@needs_c
def test_c_run_with_the_tangent_is_the_plain_one() -> None:
    """The switch hooks only read the stepper's state (and give the forces' time slot back): the C run with
    the tangent is the plain library's bit for bit, through the spring disk's five switches and the pushed
    block's slide (forces of time)."""
    import test_friction

    a, b = (
        run("spring_disk", "c", "trapezoid", [0.0, 1.0, 0.0], [2.0, 0.0, 2.0], 0.01, 3.0, sens=s)
        for s in (1, 0)
    )
    assert np.array_equal(a.q, b.q) and np.array_equal(a.p, b.p)
    s = vcigen.build(test_friction.block(), backend="c")
    a, b = (
        s.simulate(
            [0.0, 0.0], [0.0, 0.0], 0.01, t_end=1.6, params={"F": 3.0}, sensitivities=w, progress=False
        )
        for w in (True, False)
    )
    assert np.array_equal(a.q, b.q) and np.array_equal(a.p, b.p)
