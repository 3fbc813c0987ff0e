"""An isotropic cone (two tangents) held at an impact while held takes Coulomb's cone in the impulse law
(``SustainedSteps._impulse_law`` with ``_law_slide``, :func:`vcigen.friction.cone_slide`; C ``impulse_law``
with ``law_slide``, ``cone_slide`` in ``templates/sustained_impacts.c.j2``; MATH.md *Friction*).

It sticks (``w+ = 0``, ``|F| <= mu N``) or slips with ``F = -mu N w+ / |w+|``, ``w+`` its sliding velocity
*after* the impact. Before: slipping, it took its normal impulse only; sticking, a stick impulse out of its
cone was a ``SolverError``.

**Ball on a rough floor into a sloped smooth wall.** ``q = (x, y, z, ax, ay)``, ``m = 1``, ``I = 0.4``, ``r =
1``, floor ``z >= r`` with ``mu`` on the tangents ``(x - r ay, y + r ax)`` (sliding velocity ``w = (xd - r
ayd, yd + r axd)``), wall ``W - r - x cos b - z sin b >= 0`` (``b = 0.7``, normal pointing down into the
floor, restitution ``e = 0.8``), hit at ``x = X_HIT``. Slipping on the floor, ``w`` keeps its direction ``s``
and ``w' = -mu g k m s``, ``k = 1/m + r^2/I``, the centre ``-mu g s``, ``axd' = -mu m g s_2 r / I``, ``ayd' =
mu m g s_1 r / I``, until ``w = 0``; then it rolls at constant velocity. At the wall (velocities ``u, v, ωx,
ωy`` before, ``w-`` the sliding): the wall makes ``xd+ = -e u``; with the floor's ``zd+ = 0`` its normal
impulse is ``N = tan b (m (1 + e) u + F_1)``, and ``yd+ = v + F_2/m``, ``axd+ = ωx + F_2 r/I``, ``ayd+ = ωy -
F_1 r/I``, so ``w+ = (c_1 + F_1 r^2/I, w-_2 + F_2 k)``, ``c_1 = -e u - r ωy``:

* stick: ``F = (-c_1 I/r^2, -w-_2/k)`` if ``|F| <= mu N``;
* slip: ``F = -mu N (cos θ, sin θ)``, ``N = tan b m (1 + e) u / (1 + mu tan b cos θ)``, θ the root of
  ``(c_1 - mu N cos θ r^2/I) sin θ = (w-_2 - mu N sin θ k) cos θ`` with ``w+ . (cos θ, sin θ) > 0`` (one root;
  scanned on 7200 angles (offset), then brentq: a scalar equation, not vcigen's ``sigma`` search).

Every piece is a constant acceleration, so the discrete map is exact (the impact and the stop located): every
grid point on the closed form to ``TOL``, both backends, trapezoid and midpoint.
"""

from __future__ import annotations

import math
from functools import cache

import hard_scenes
import numpy as np
import pytest
import sympy as sp
from scipy.optimize import brentq
from test_impulse_law_friction import max_error
from test_sensitivity import BACKENDS, assert_lost, held_mode

import vcigen
from vcigen.friction import cone_impulse, cone_slide

G = 9.81
H = 0.01
RULES = ("trapezoid", "midpoint")
TOL = 1e-13
needs_c = pytest.mark.skipif(
    hard_scenes.c_backend_problem() is not None, reason=str(hard_scenes.c_backend_problem())
)
M, INERTIA, R, SLOPE, E, X_HIT = 1.0, 0.4, 1.0, 0.7, 0.8, 0.16
K = 1 / M + R * R / INERTIA
# case -> (mu, v0 = (xd, yd, zd, axd, ayd), mode at the impact, sticking before it)
CASES = {
    # slipping, the slip turns through the impact (before: frictionless, the slip kept its side)
    "slip_turns": (0.2, (1.05, 0.5, 0.0, 1.0, -0.3), "slip"),
    # slipping, the sliding impulse would reverse it: it sticks within the cone
    "slip_sticks": (0.2, (1.05, 0.15, 0.0, -0.3, -1.5), "stick"),
    # rolling (sticking) into the wall, its stick impulse out of the cone: slips on its edge (was an error)
    "roll_slips": (0.2, (1.05, 0.5, 0.0, -0.5, 1.05), "slip"),
    # rolling into the wall with mu = 0.6: the stick holds (unchanged)
    "roll_sticks": (0.6, (1.05, 0.5, 0.0, -0.5, 1.05), "stick"),
}


def ball() -> vcigen.Model:
    """The ball of the module docstring (``mu`` a parameter)."""
    x, y, z, ax, ay = sp.symbols("x y z ax ay")
    xd, yd, zd, axd, ayd = sp.symbols("xd yd zd axd ayd")
    b, w, mu = sp.symbols("b W mu")
    par = {b: SLOPE, mu: 0.2, w: R + X_HIT * math.cos(SLOPE) + R * math.sin(SLOPE)}
    return vcigen.Model(
        name="ilc_ball",
        q=[x, y, z, ax, ay],
        qdot=[xd, yd, zd, axd, ayd],
        lagrangian=M / 2 * (xd**2 + yd**2 + zd**2) + INERTIA / 2 * (axd**2 + ayd**2) - M * G * z,
        contacts={"floor": z - R, "wall": w - R - x * sp.cos(b) - z * sp.sin(b)},
        params=par,
        restitution={"wall": E},
        friction={"floor": (mu, (x - R * ay, y + R * ax))},
    )


@cache
def simulator(backend: str, rule: str = "trapezoid") -> vcigen.Simulator:
    return vcigen.build(ball(), backend=backend, rule=rule)


def run(case: str, backend: str, rule: str = "trapezoid", t_end: float = 0.7, **kw) -> vcigen.Result:
    mu, v0, _ = CASES[case]
    sim = simulator(backend, rule)
    return sim.simulate(
        [0.0, 0.0, R, 0.0, 0.0], list(v0), H, t_end=t_end, params={"mu": mu}, progress=False, **kw
    )


def slide(t: np.ndarray, t0: float, q0, v0, mu: float):
    """``(q, v)`` (columns ``x, y, ax, ay``; ``xd, yd, axd, ayd``) at ``t >= t0`` from ``(q0, v0)`` at ``t0``
    on the floor: slipping along the constant direction of ``w`` until it stops, then rolling; and the stop's
    time."""
    q0, v0 = np.asarray(q0, float), np.asarray(v0, float)
    w0 = np.array([v0[0] - R * v0[3], v0[1] + R * v0[2]])
    nw = math.hypot(*w0)
    s = w0 / nw if nw > 0 else np.zeros(2)
    acc = np.array(
        [-mu * G * s[0], -mu * G * s[1], -mu * M * G * s[1] * R / INERTIA, mu * M * G * s[0] * R / INERTIA]
    )
    t_stop = t0 + nw / (mu * G * K * M)
    d = np.clip(t - t0, 0.0, t_stop - t0)[:, None]
    after = np.clip(t - t_stop, 0.0, None)[:, None]
    v = v0 + acc * d
    return q0 + v0 * d + acc * d * d / 2 + v * after, v, t_stop


def impact(case: str) -> dict:
    """The impact by the closed form of the module docstring: its time, the state before and after, the mode,
    the friction impulse ``F``, the floor's ``N`` and the wall's ``P``."""
    mu, v0, _ = CASES[case]
    t_stop = slide(np.array([0.0]), 0.0, [0, 0, 0, 0], [v0[0], v0[1], v0[3], v0[4]], mu)[2]
    # the time x reaches X_HIT: slipping (x = u0 t - a t^2 / 2) or, past the stop, rolling
    x_stop, u_stop = slide(np.array([t_stop]), 0.0, [0, 0, 0, 0], [v0[0], v0[1], v0[3], v0[4]], mu)[:2]
    if x_stop[0, 0] >= X_HIT:
        a = mu * G * (v0[0] - R * v0[4]) / math.hypot(v0[0] - R * v0[4], v0[1] + R * v0[3])
        ts = (v0[0] - math.sqrt(v0[0] ** 2 - 2 * a * X_HIT)) / a
    else:
        ts = t_stop + (X_HIT - x_stop[0, 0]) / u_stop[0, 0]
    q, v, _ = slide(np.array([ts]), 0.0, [0, 0, 0, 0], [v0[0], v0[1], v0[3], v0[4]], mu)
    q, v = q[0], v[0]
    u, vy, wx, wy = v
    c1, w2 = -E * u - R * wy, vy + R * wx
    tb = math.tan(SLOPE)
    f = np.array([-c1 * INERTIA / R**2, -w2 / K])
    n = tb * (M * (1 + E) * u + f[0])
    mode = "stick"
    if math.hypot(*f) > mu * n:
        mode = "slip"

        def normal(th):
            return tb * M * (1 + E) * u / (1 + mu * tb * math.cos(th))

        def cross(th):
            nn = normal(th)
            return (c1 - mu * nn * math.cos(th) * R**2 / INERTIA) * math.sin(th) - (
                w2 - mu * nn * math.sin(th) * K
            ) * math.cos(th)

        def along(th):
            nn = normal(th)
            return (c1 - mu * nn * math.cos(th) * R**2 / INERTIA) * math.cos(th) + (
                w2 - mu * nn * math.sin(th) * K
            ) * math.sin(th)

        grid = np.linspace(-math.pi, math.pi, 7201) + 1e-3 * math.sqrt(
            2
        )  # no grid point on a root (nor 0, pi)
        vals = [cross(x) for x in grid]
        roots = [
            brentq(cross, grid[i], grid[i + 1], xtol=1e-16, rtol=8.9e-16, maxiter=500)
            for i in range(len(grid) - 1)
            if vals[i] * vals[i + 1] < 0
        ]
        roots = [th for th in roots if along(th) > 0 and normal(th) > 0]
        assert len(roots) == 1, roots
        th = roots[0]
        n = normal(th)
        f = -mu * n * np.array([math.cos(th), math.sin(th)])
    p_wall = (M * (1 + E) * u + f[0]) / math.cos(SLOPE)
    v_plus = np.array([-E * u, vy + f[1] / M, wx + f[1] * R / INERTIA, wy - f[0] * R / INERTIA])
    w_plus = np.array([v_plus[0] - R * v_plus[3], v_plus[1] + R * v_plus[2]])
    return {
        "t": ts,
        "q": q,
        "v": v,
        "v+": v_plus,
        "w-": np.array([u - R * wy, w2]),
        "w+": w_plus,
        "mode": mode,
        "F": f,
        "N": n,
        "P": p_wall,
    }


def closed_form(t: np.ndarray, case: str) -> tuple[np.ndarray, np.ndarray]:
    """``(q, v)`` on the columns ``x, y, ax, ay`` at ``t``: to the wall, the impact, slipping, rolling."""
    mu, v0, _ = CASES[case]
    im = impact(case)
    q1, v1, _ = slide(t, 0.0, [0, 0, 0, 0], [v0[0], v0[1], v0[3], v0[4]], mu)
    q2, v2, _ = slide(t, im["t"], im["q"], im["v+"], mu)
    before = (t <= im["t"])[:, None]
    return np.where(before, q1, q2), np.where(before, v1, v2)


def test_the_cases_are_what_they_claim() -> None:
    """The closed forms' modes, and the slip direction of ``slip_turns`` turning through the impact."""
    for case, (_, _, mode) in CASES.items():
        im = impact(case)
        assert im["mode"] == mode, case
        assert (np.abs(im["w-"]).max() > 1e-3) == case.startswith("slip"), case
    im = impact("slip_turns")
    turn = math.degrees(math.atan2(im["w+"][1], im["w+"][0]) - math.atan2(im["w-"][1], im["w-"][0]))
    assert abs(turn) > 60.0, turn


@pytest.mark.parametrize("rule", RULES)
@pytest.mark.parametrize("backend", BACKENDS)
@pytest.mark.parametrize("case", sorted(CASES))
def test_the_ball_run_is_the_closed_form(case: str, backend: str, rule: str) -> None:
    """``x, y, ax, ay`` and their rates at every grid point are the closed form's, the ball stays on the
    floor, the wall's impulse is ``P``, and right after the impact it slips along ``w+`` or sticks; the
    impact's loss is the closed form's."""
    res = run(case, backend, rule)
    im_cf = impact(case)
    (im,) = res.impacts
    cols = [0, 1, 3, 4]
    q_cf, v_cf = closed_form(res.t, case)
    err = max_error(res.q, res.v, dict(zip(cols, q_cf.T)), dict(zip(cols, v_cf.T)))
    print(f"{case} ({backend}, {rule}): closed form {err:.1e}")
    assert err <= TOL, err
    assert np.abs(res.q[:, 2] - R).max() <= 1e-14 and res.active[:, 0].all() and res.liftoffs == []
    assert im.contact == "wall" and im.kind == "restitution" and abs(im.t - im_cf["t"]) <= 1e-13
    assert abs(im.impulse - im_cf["P"]) <= 1e-12 * im_cf["P"]
    kin = 0.5 * M * (im_cf["v"][0] ** 2 + im_cf["v"][1] ** 2) + 0.5 * INERTIA * (im_cf["v"][2:] ** 2).sum()
    kin_p = (
        0.5 * M * (im_cf["v+"][0] ** 2 + im_cf["v+"][1] ** 2) + 0.5 * INERTIA * (im_cf["v+"][2:] ** 2).sum()
    )
    assert abs((im.energy_before - im.energy_after) - (kin - kin_p)) <= 1e-12
    v = res.v[im.step + 1]
    w_after = np.array([v[0] - R * v[4], v[1] + R * v[3]])
    if im_cf["mode"] == "slip":
        assert math.hypot(*w_after) > 0.1
    else:
        assert np.abs(w_after).max() <= 1e-13


@needs_c
@pytest.mark.parametrize("rule", RULES)
@pytest.mark.parametrize("case", sorted(CASES))
def test_c_equals_casadi(case: str, rule: str) -> None:
    """The C stepper's run is the CasADi one's: the same impacts and modes, states to round-off."""
    a, b = (run(case, backend, rule) for backend in ("casadi", "c"))
    assert held_mode(a) == held_mode(b)
    err = max(np.abs(b.q - a.q).max(), np.abs(b.p - a.p).max())
    print(f"{case} ({rule}): C - CasADi {err:.1e}")
    assert err <= 1e-13, err


# case -> the tangent's break at the impact: a cone that switched (slip -> stick, stick -> slip) is a friction
# switch; one slipping on through the impact (slip_turns) carries its tangent since stop 28 (below)
BREAKS = {
    "slip_sticks": "friction switch in a held step",
    "roll_slips": "friction switch in a held step",
}


@pytest.mark.parametrize("backend", BACKENDS)
@pytest.mark.parametrize("case", sorted(BREAKS))
def test_the_tangent_breaks_at_a_cones_friction_switch(case: str, backend: str) -> None:
    """The tangent does not carry a held cone's switch at an impact: the step breaks with a named reason,
    finite before, on both backends."""
    res = run(case, backend, sensitivities=True)
    (im,) = res.impacts
    assert assert_lost(res, BREAKS[case]) == im.step
    assert res.sensitivity_breaks[0] == (im.step, BREAKS[case])


@pytest.mark.parametrize("backend", BACKENDS)
def test_the_tangent_through_a_cone_slipping_on_against_central_differences(backend: str) -> None:
    """``slip_turns``: the cone slips on through the impact, its sliding impulse ``-mu N w+ / |w+|`` turning
    with the sliding after it (by 104 degrees; ``Tracker._cone_slides``, C ``sens_cone_slides``; before stop
    28 a break, ``"friction at an impact"``). The state at t = 0.2 (the impact at step 17, still slipping; it
    rolls from step 21, a cone's stop the tangent does not carry) against central differences of whole runs
    (eps 1e-6) in ``q0[x], q0[y]``, ``v0`` but its ``z``, ``mu`` and the wall's ``W`` and ``b``, to 1e-7 of
    the largest entry."""
    sim = simulator(backend)
    mu, v0, _ = CASES["slip_turns"]
    q0, t_end = [0.0, 0.0, R, 0.0, 0.0], 0.2
    defaults = {str(k): float(v) for k, v in sim.model.params.items()}

    def go(q, v, par, sens=False):
        return sim.simulate(q, v, H, t_end=t_end, params=par, progress=False, sensitivities=sens)

    res = go(q0, list(v0), {"mu": mu}, True)
    (im,) = res.impacts
    assert res.sensitivity_breaks == [] and im.step == 17

    def end(name: str, e: float) -> np.ndarray:
        q, v, par = list(q0), list(v0), {"mu": mu}
        if name in ("mu", "W", "b"):
            par[name] = (mu if name == "mu" else defaults[name]) + e
        else:
            (q if name[0] == "q" else v)[["x", "y", "z", "ax", "ay"].index(name[3:-1])] += e
        r = go(q, v, par)
        assert [i.step for i in r.impacts] == [im.step]
        return np.concatenate([r.q[-1], r.p[-1]])

    worst = 0.0
    for name in ("q0[x]", "q0[y]", "v0[x]", "v0[y]", "v0[ax]", "v0[ay]", "mu", "W", "b"):
        fd = (end(name, 1e-6) - end(name, -1e-6)) / 2e-6
        exact = res.sensitivity[-1, :, res.sensitivity_names.index(name)]
        worst = max(worst, float(np.abs(fd - exact).max() / max(1.0, np.abs(exact).max())))
    print(f"{backend}: a cone slipping on through an impact, tangent vs central differences {worst:.1e}")
    assert worst <= 1e-7


def test_cone_slide_is_coulombs_law() -> None:
    """:func:`cone_slide` on random data: ``m`` against the velocity after ``g + H m`` and on the cone's edge
    ``|m| = mu (a - b.m)`` (to 1e-12 relative); None where the stick is inside; with ``b = 0`` and ``H``
    symmetric it is :func:`cone_impulse`'s minimiser (to 1e-12)."""
    rng = np.random.default_rng(7)
    slid = 0
    for _ in range(2000):
        a_ = rng.normal(size=(2, 2))
        h = a_ @ a_.T + 0.05 * np.eye(2)
        if rng.random() < 0.3:
            h = h + rng.normal(scale=0.2, size=(2, 2))  # non-symmetric (one-tangent edges in the law)
        g = rng.normal(size=2) * rng.choice([0.1, 1.0, 10.0])
        b = rng.normal(size=2) * rng.choice([0.0, 0.3])
        mu, a = rng.uniform(0.05, 1.0), rng.uniform(0.1, 2.0)
        hh = (h[0, 0], h[0, 1], h[1, 0], h[1, 1])
        if np.linalg.det(h) <= 0 or np.trace(h) <= 0:
            continue
        m = cone_slide(tuple(g), hh, tuple(b), mu, a)
        stick = -np.linalg.solve(h, g)
        inside = np.linalg.norm(stick) <= mu * (a - b @ stick)
        assert (m is None) == inside
        if m is None:
            continue
        slid += 1
        m = np.array(m)
        w = g + h @ m
        assert np.linalg.norm(m) > 0 and abs(m[0] * w[1] - m[1] * w[0]) <= 1e-12 * np.linalg.norm(m) * max(
            np.linalg.norm(w), 1
        )
        assert m @ w <= 0
        assert abs(np.linalg.norm(m) - mu * (a - b @ m)) <= 1e-12 * (1 + np.linalg.norm(m))
        if not b.any() and np.allclose(h, h.T, rtol=0, atol=0):
            ref = cone_impulse(tuple(g), (h[0, 0], h[0, 1], h[1, 1]), (0.0, 0.0), mu, a)
            assert np.abs(m - np.array(ref)).max() <= 1e-12 * (1 + np.abs(m).max())
    assert slid > 500
