"""The figures of the README's contact-regime section (sustained contact, lift-off, Zeno, constraints).

    .venv/bin/python bench/sustained_figures.py [--backend c casadi] [--long 1000000]

Prints, per backend:

* lift-off from a dome ``sqrt(x^2 + y^2) >= 1`` (q0 = top, v0 = 0.1): the located lift-off time
  against scipy (solve_ivp DOP853, rtol = atol = 1e-12, event where the normal force
  g cos(theta) - theta'^2 vanishes) at h = 0.01, 0.005, 0.0025 and the fitted order;
* Zeno: a ball with e = 0.5 dropped from y = 1: impacts, the time it is held against the Zeno
  time t1 + 2 e v1 / (g (1 - e)), and the resting force against m g;
* sustained sliding in a frictionless bowl ``1 - x^2 - y^2 >= 0`` (start at the bottom with speed
  8, h = 0.01): E_d over ``--long`` steps (C; 1e5 on CasADi): max relative deviation and the drift
  (least-squares slope times the run length), |phi| and the smallest contact force;
* a pendulum held by a bilateral rod: constraint residual and E_d deviation over 1e5 steps.
"""

from __future__ import annotations

import argparse
import math
import time

import numpy as np
import sympy as sp
from scipy.integrate import solve_ivp

import vcigen

X, Y, XD, YD = sp.symbols("x y xd yd")
G = 9.81
LAGRANGIAN = (XD**2 + YD**2) / 2 - G * Y


def dome_liftoff_exact(v0: float = 0.1) -> float:
    """Lift-off time from the top of a unit dome: the normal force g cos(th) - th'^2 vanishes."""

    def rhs(_, s):
        return [s[1], G * math.sin(s[0])]

    def leaves(_, s):
        return G * math.cos(s[0]) - s[1] ** 2

    leaves.terminal = True
    sol = solve_ivp(rhs, (0, 5), [0.0, v0], method="DOP853", rtol=1e-12, atol=1e-12, events=leaves)
    return float(sol.t_events[0][0])


def dome(backend: str) -> None:
    model = vcigen.Model(
        name="fig_dome",
        q=[X, Y],
        qdot=[XD, YD],
        lagrangian=LAGRANGIAN,
        contacts={"dome": sp.sqrt(X**2 + Y**2) - 1},
    )
    sim, exact = vcigen.build(model, backend=backend), dome_liftoff_exact()
    hs, errs = [0.01, 0.005, 0.0025], []
    for h in hs:
        res = sim.simulate([0.0, 1.0], [0.1, 0.0], h, t_end=1.6)
        errs.append(abs(res.liftoffs[0][0] - exact))
    order = np.polyfit(np.log(hs), np.log(errs), 1)[0]
    print(
        f"  dome lift-off (exact t = {exact:.10f}): errors "
        + ", ".join(f"{e:.2e}" for e in errs)
        + f" at h = {hs}; order {order:.2f}"
    )


def zeno(backend: str, e: float = 0.5, h: float = 0.001) -> None:
    es = sp.Symbol("e")
    model = vcigen.Model(
        name="fig_ball",
        q=[X, Y],
        qdot=[XD, YD],
        lagrangian=LAGRANGIAN,
        contacts={"floor": Y},
        params={es: e},
        restitution={"floor": es},
    )
    res = vcigen.build(model, backend=backend).simulate([0.0, 1.0], [0.3, 0.0], h, t_end=3.0)
    v1 = math.sqrt(2 * G)
    t_inf = v1 / G + 2 * e * v1 / (G * (1 - e))
    held = res.t[np.argmax(res.active[:, 0])]
    kinds = {k[8:]: int(v) for k, v in res.stats.items() if k.startswith("impacts_") and v}
    rest = res.contact_force[res.active[1:, 0] & res.active[:-1, 0], 0]
    print(
        f"  Zeno ball e = {e}, h = {h}: {res.n_impacts} impacts {kinds}; held from t = {held:.4f} "
        f"(Zeno time {t_inf:.4f}, {held - t_inf:+.1e}); resting force max |lambda - m g| = "
        f"{np.abs(rest - G).max():.1e}; max impacts in one step "
        f"{max(np.bincount([i.step for i in res.impacts]))}"
    )


def bowl(backend: str, steps: int) -> None:
    model = vcigen.Model(
        name="fig_bowl", q=[X, Y], qdot=[XD, YD], lagrangian=LAGRANGIAN, contacts={"rim": 1 - X**2 - Y**2}
    )
    sim = vcigen.build(model, backend=backend)
    wall = time.perf_counter()
    res = sim.simulate([0.0, -1.0], [8.0, 0.0], 0.01, t_end=steps * 0.01)
    wall = time.perf_counter() - wall
    rel = (res.energy - res.energy[0]) / abs(res.energy[0])
    drift = np.polyfit(np.arange(rel.size), rel, 1)[0] * rel.size
    phi = np.abs(1 - (res.q**2).sum(axis=1)).max()
    print(
        f"  bowl, {res.stats['steps']} steps held (active throughout: {bool(res.active.all())}, "
        f"{res.n_impacts} impacts, {len(res.liftoffs)} lift-offs): "
        f"max |E_d - E0|/E0 = {np.abs(rel).max():.2e}, "
        f"drift over the run {drift:.1e}, max |phi| {phi:.1e}, min force {res.contact_force.min():.3f}; "
        f"{wall:.2f} s"
    )


def pendulum(backend: str, steps: int = 100_000) -> None:
    model = vcigen.Model(
        name="fig_rod", q=[X, Y], qdot=[XD, YD], lagrangian=LAGRANGIAN, constraints={"rod": X**2 + Y**2 - 1}
    )
    res = vcigen.build(model, backend=backend).simulate(
        [math.sin(1.0), -math.cos(1.0)], [0.0, 0.0], 0.01, t_end=steps * 0.01
    )
    rel = (res.energy - res.energy[0]) / abs(res.energy[0])
    drift = np.polyfit(np.arange(rel.size), rel, 1)[0] * rel.size
    residual = np.abs((res.q**2).sum(axis=1) - 1).max()
    print(
        f"  rod pendulum, {res.stats['steps']} steps: max |g(q)| = {residual:.1e}, "
        f"max |E_d - E0|/E0 = {np.abs(rel).max():.2e}, drift over the run {drift:.1e}"
    )


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--backend", nargs="+", default=["c", "casadi"], choices=["c", "casadi"])
    ap.add_argument("--long", type=int, default=1_000_000, help="steps of the bowl run in C")
    a = ap.parse_args()
    for backend in a.backend:
        print(f"[{backend}]")
        dome(backend)
        zeno(backend)
        bowl(backend, a.long if backend == "c" else min(a.long, 100_000))
        pendulum(backend, 100_000 if backend == "c" else 20_000)


if __name__ == "__main__":
    main()
