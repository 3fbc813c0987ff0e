"""Forced scenes and their closed forms (MATH.md, *Forcing*), for the tests of Lagrange-d'Alembert forces.

The damped, driven oscillator ``x'' + c x' + w^2 x = A cos(W t)`` against a wall ``x <= d`` with
restitution ``e``: between impacts the flow is the exact solution of the linear ODE (homogeneous plus
particular), an impact is located on it by ``scipy.optimize.brentq`` to round-off, and the velocity leaves
with ``-e`` times its incoming value. A vibratory conveyor's particle (:func:`conveyor_reference`): its
phases on a rough vibrating plate chained by events. No vcigen inside.
"""

from __future__ import annotations

import math

import numpy as np
import sympy as sp
from scipy.integrate import solve_ivp
from scipy.optimize import brentq

import vcigen

DAMPING, STIFFNESS, AMPLITUDE, DRIVE, WALL, REST = 0.3, 4.0, 2.0, 1.7, 0.5, 0.8
G = 9.81  # gravity (hard_scenes.G)


def driven_oscillator(time_symbol: bool = True) -> vcigen.Model:
    """A unit mass on a spring ``k``, viscous damping ``c``, drive ``A cos(W t)``, a wall at ``x = d``."""
    x, xd, t = sp.symbols("x xd t")
    c, k, A, W, d, e = sp.symbols("c k A W d e")
    drive = A * sp.cos(W * t) if time_symbol else A
    return vcigen.Model(
        name="driven" if time_symbol else "pushed",
        q=[x],
        qdot=[xd],
        lagrangian=xd**2 / 2 - k * x**2 / 2,
        contacts={"wall": d - x},
        params={c: DAMPING, k: STIFFNESS, A: AMPLITUDE, W: DRIVE, d: WALL, e: REST},
        restitution={"wall": e},
        forces=[-c * xd + drive],
        time=t if time_symbol else None,
    )


def pendulum_wall() -> vcigen.Model:
    """A damped, driven pendulum ``L = thd^2/2 + 4 cos th`` (V not quadratic) against a wall at ``th = d``
    (restitution ``e``): the balance's terms that are exact only for quadratic V (``vcigen.work``)."""
    th, thd, t = sp.symbols("th thd t")
    c, A, W, e, d = sp.symbols("c A W e d")
    return vcigen.Model(
        name="pendulum_wall",
        q=[th],
        qdot=[thd],
        lagrangian=thd**2 / 2 + 4 * sp.cos(th),
        contacts={"wall": d - th},
        restitution={"wall": e},
        params={c: 0.3, A: 2.5, W: 1.7, e: 0.8, d: 0.6},
        forces=[-c * thd + A * sp.cos(W * t)],
        time=t,
    )


def polar_particle(rim: float | None = None) -> vcigen.Model:
    """A particle in polar coordinates (mass matrix ``diag(1, r^2)``) on a spring ``2 (r - 1)^2`` in a
    field ``0.3 x``, damped (c = 0.3), driven radially by ``cos 1.7 t`` and turned by ``sin(0.3 t)/2``;
    with ``rim``, inside a rim ``r <= rim`` (restitution 0.8)."""
    r, th, rd, thd, t = sp.symbols("r th rd thd t")
    c, A, W, R, e = sp.symbols("c A W R e")
    params = {c: 0.3, A: 1.0, W: 1.7}
    walls = {}
    if rim is not None:
        params |= {R: rim, e: 0.8}
        walls = {"contacts": {"rim": R - r}, "restitution": {"rim": e}}
    return vcigen.Model(
        name="polar_forced" if rim is None else "polar_rim",
        q=[r, th],
        qdot=[rd, thd],
        lagrangian=(rd**2 + r**2 * thd**2) / 2 - 2 * (r - 1) ** 2 - sp.Rational(3, 10) * r * sp.cos(th),
        params=params,
        forces=[-c * rd + A * sp.cos(W * t), -c * r**2 * thd + sp.sin(sp.Rational(3, 10) * t) / 2],
        time=t,
        **walls,
    )


def rod_pendulum(wall: float | None = None, potential: sp.Expr | None = None) -> vcigen.Model:
    """A particle on a rod ``x^2 + y^2 = 1`` (a bilateral constraint) under gravity ``4 y``, damped (c = 0.3)
    and driven along x by ``2.5 cos 1.7 t``; with ``wall``, against a wall ``x <= wall`` (e = 0.8);
    ``potential`` (of ``x``, ``y``) in place of ``4 y``."""
    x, y, xd, yd, t = sp.symbols("x y xd yd t")
    c, A, W, e, d = sp.symbols("c A W e d")
    params = {c: 0.3, A: 2.5, W: 1.7}
    walls = {}
    if wall is not None:
        params |= {e: 0.8, d: wall}
        walls = {"contacts": {"wall": d - x}, "restitution": {"wall": e}}
    pot = 4 * y if potential is None else potential.xreplace({sp.Symbol("x"): x, sp.Symbol("y"): y})
    return vcigen.Model(
        name="rod_forced" + ("" if wall is None else "_wall") + ("" if potential is None else "_v"),
        q=[x, y],
        qdot=[xd, yd],
        lagrangian=(xd**2 + yd**2) / 2 - pot,
        constraints={"rod": x**2 + y**2 - 1},
        params=params,
        forces=[-c * xd + A * sp.cos(W * t), -c * yd],
        time=t,
        **walls,
    )


class LinearFlow:
    """Exact flow of ``x'' + c x' + k x = A cos(W t)`` (underdamped) from ``(t0, x0, v0)``."""

    def __init__(self, c: float, k: float, A: float, W: float) -> None:
        self.zeta_w = c / 2
        self.wd = math.sqrt(k - self.zeta_w**2)
        den = (k - W**2) ** 2 + (c * W) ** 2
        self.a, self.b, self.W = A * (k - W**2) / den, A * c * W / den, W  # x_p = a cos + b sin

    def particular(self, t):
        W = self.W
        return self.a * np.cos(W * t) + self.b * np.sin(W * t), W * (
            -self.a * np.sin(W * t) + self.b * np.cos(W * t)
        )

    def __call__(self, t0: float, x0: float, v0: float, t):
        xp0, vp0 = self.particular(t0)
        c1 = x0 - xp0
        c2 = (v0 - vp0 + self.zeta_w * c1) / self.wd
        s = np.asarray(t) - t0
        env = np.exp(-self.zeta_w * s)
        cs, sn = np.cos(self.wd * s), np.sin(self.wd * s)
        xh = env * (c1 * cs + c2 * sn)
        vh = env * (-self.zeta_w * (c1 * cs + c2 * sn) + self.wd * (-c1 * sn + c2 * cs))
        xp, vp = self.particular(t)
        return xh + xp, vh + vp


def _height(s: float, flow, t: float, x: float, v: float, wall: float) -> float:
    return float(flow(t, x, v, s)[0]) - wall


WINDOW = 8192  # grid points of driven_exact's search evaluated at once


def driven_exact(
    x0: float,
    v0: float,
    t_end: float,
    t0: float = 0.0,
    wall: float = WALL,
    e: float = REST,
    flow: LinearFlow | None = None,
):
    """``(x(t_end), v(t_end), impact times)`` of the driven oscillator against the wall, exactly (``flow``:
    another ``LinearFlow`` than this module's coefficients)."""
    flow = flow or LinearFlow(DAMPING, STIFFNESS, AMPLITUDE, DRIVE)
    t, x, v, hits = t0, x0, v0, []
    probe = 1e-3
    while True:
        # the first crossing of x = wall after t, on a fine grid, then brentq to round-off
        grid = np.arange(t + probe, t_end + probe, probe)
        grid[-1] = min(grid[-1], t_end)
        # the flow on the grid a window at a time, from its start: the same points and values as on the
        # whole grid at once (elementwise), so the same first crossing; a window of 8 s holds the next
        # impact, where the whole grid to t_end = 1000 cost 270 x 1e6 evaluations (27 s)
        i = None
        for start in range(0, grid.size, WINDOW):
            xs, _ = flow(t, x, v, grid[start : start + WINDOW])
            above = np.flatnonzero(xs > wall)
            if above.size:
                i = start + int(above[0])
                break
        if i is None:
            xe, ve = flow(t, x, v, t_end)
            return float(xe), float(ve), hits
        lo = t if i == 0 else grid[i - 1]
        ti = brentq(_height, lo, grid[i], args=(flow, t, x, v, wall), xtol=1e-15, rtol=1e-15)
        _, vi = flow(t, x, v, ti)
        hits.append(ti)
        t, x, v = ti, wall, -e * float(vi)


def driven_exact_grid(
    x0: float, v0: float, ts: np.ndarray, wall: float = WALL, e: float = REST, flow: LinearFlow | None = None
) -> np.ndarray:
    """``x`` of the exact driven oscillator (:func:`driven_exact`) at every time of ``ts``."""
    flow = flow or LinearFlow(DAMPING, STIFFNESS, AMPLITUDE, DRIVE)
    _, _, hits = driven_exact(x0, v0, float(ts[-1]), float(ts[0]), wall, e, flow)
    out = np.empty(ts.size)
    t, x, v = float(ts[0]), x0, v0
    for tb in [*hits, math.inf]:
        sel = (ts >= t) & (ts < tb)
        out[sel] = flow(t, x, v, ts[sel])[0]
        if tb == math.inf:
            break
        _, vb = flow(t, x, v, tb)
        t, x, v = tb, wall, -e * float(vb)
    return out


def driven_wall_errors(sim, hs: list[float]) -> tuple[list[float], list[float]]:
    """Per ``h``: the driven oscillator's max grid error against :func:`driven_exact_grid` from rest over
    ``t = 10`` and the largest impact-time error (its two restitution impacts, checked)."""
    errs, hit_errs = [], []
    for h in hs:
        res = sim.simulate(q0=[0.0], v0=[0.0], h=h, t_end=10.0)
        errs.append(float(np.max(np.abs(res.q[:, 0] - driven_exact_grid(0.0, 0.0, res.t)))))
        _, _, hits = driven_exact(0.0, 0.0, float(res.t[-1]))
        assert len(res.impacts) == len(hits) == 2
        assert all(im.kind == "restitution" for im in res.impacts)
        hit_errs.append(max(abs(im.t - th) for im, th in zip(res.impacts, hits)))
    return errs, hit_errs


def conveyor_reference(p, t_end: float):
    """A particle on a rough plate vibrating as ``A sin(W t)`` along the angle ``beta`` from it
    (``examples/forced/conveyor.py``), in the plate's frame, ``e = 0``, from rest on the plate: the events
    ``(kind, t)`` (slide, stop, lift, land) and ``(x, y)`` at a time. On the plate the normal force is
    ``N = g - a sin beta`` (``a = A W^2 sin(W t)``) and friction ``mu N`` holds it while
    ``|a cos beta| <= mu N``, else it slides; where ``N`` falls to 0 it flies, and lands with Coulomb's
    impulse (the sliding speed falls by at most ``mu`` times the normal one). Each phase by DOP853
    (rtol 1e-12) to its events."""
    drive = lambda t: p["A"] * p["W"] ** 2 * math.sin(p["W"] * t)  # noqa: E731
    cb, sb, mu = math.cos(p["beta"]), math.sin(p["beta"]), p["mu"]
    normal = lambda t: G - drive(t) * sb  # noqa: E731
    opts = dict(method="DOP853", rtol=1e-12, atol=1e-13, max_step=0.2 / p["W"])
    t, s, mode = 0.0, np.zeros(4), "rest"
    events: list[tuple[str, float]] = []
    pieces = []

    def run(rhs, stops):
        sol = solve_ivp(rhs, (t, t_end), s, events=stops, dense_output=True, **opts)
        pieces.append((t, sol.t[-1], sol.sol))
        hits = [(float(te[0]), i) for i, te in enumerate(sol.t_events) if te.size]
        return (min(hits), sol) if hits and sol.status == 1 else (None, sol)

    while t < t_end:
        if mode == "rest":  # on the plate at a sliding speed of 0
            if normal(t) <= 0.0:
                mode = "flight"
                continue
            if abs(drive(t) * cb) > mu * normal(t):
                mode, way = "slide", math.copysign(1.0, drive(t) * cb)
                events.append(("slide", t))
                continue

            def lift(tt, z):
                return normal(tt)

            def slide(tt, z):
                return mu * normal(tt) - abs(drive(tt) * cb)

            lift.terminal = slide.terminal = True
            hit, sol = run(lambda tt, z: [0.0, 0.0, 0.0, 0.0], [lift, slide])
            if hit is None:
                break
            t = hit[0]
            if hit[1] == 0:
                mode = "flight"
                events.append(("lift", t))
            else:
                mode, way = "slide", math.copysign(1.0, drive(t) * cb)
                events.append(("slide", t))
        elif mode == "slide":

            def stop(tt, z, t0=t, way=way):
                return z[2] if tt > t0 + 1e-9 else way

            def sliding(tt, z, way=way):
                return [z[2], 0.0, drive(tt) * cb - mu * normal(tt) * way, 0.0]

            def lift(tt, z):
                return normal(tt)

            stop.terminal = lift.terminal = True
            hit, sol = run(sliding, [stop, lift])
            if hit is None:
                break
            t, s = hit[0], sol.sol(hit[0]).copy()
            if hit[1] == 0:
                s[2], mode = 0.0, "rest"
                events.append(("stop", t))
            else:
                mode = "flight"
                events.append(("lift", t))
        else:  # flight, to a landing

            def land(tt, z, t0=t):
                return z[1] if tt > t0 + 1e-9 else 1.0

            land.terminal, land.direction = True, -1
            hit, sol = run(lambda tt, z: [z[2], z[3], drive(tt) * cb, -G + drive(tt) * sb], [land])
            if hit is None:
                break
            t, s = hit[0], sol.sol(hit[0]).copy()
            events.append(("land", t))
            vx, vy = s[2], s[3]
            s[1], s[3] = 0.0, 0.0
            s[2] = vx - math.copysign(min(abs(vx), mu * abs(vy)), vx)  # Coulomb's impulse, e = 0
            if s[2] != 0.0:
                mode, way = "slide", math.copysign(1.0, s[2])
            else:
                mode = "rest"

    def at(tt: float) -> np.ndarray:
        for t0, t1, sol in pieces:
            if t0 <= tt <= t1:
                return sol(tt)[:2]
        raise ValueError(f"no reference at t = {tt}")

    return events, at
