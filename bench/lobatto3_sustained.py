"""lobatto3 against trapezoid in sustained contact and on a bilateral constraint, in generated C (issue 12).

The Cartesian pendulum (a unit particle on the rod x^2 + y^2 = 1, released at rest 1 rad from the
vertical, t = 2) and a ball sliding on a floor (held all along, t = 2): the error of q at t = 2 against
DOP853 (rtol 1e-13) on the pendulum's angle, the wall time of a run best of five and its cost per step,
and the wall time at matched error on the pendulum. Run: ``python -m bench.lobatto3_sustained`` (prints
a table; nothing is written). A loaded machine: ratios within one run only.
"""

from __future__ import annotations

import math

import numpy as np
import sympy as sp
from scipy.integrate import solve_ivp

import vcigen
from bench.lobatto3_cost import at_error, best_time

G, THETA0, T = 9.81, 1.0, 2.0
HS = [0.2, 0.1, 0.04, 0.02, 0.01, 0.005, 0.0025]


def pendulum() -> vcigen.Model:
    x, y, xd, yd = sp.symbols("x y xd yd")
    return vcigen.Model(
        name="bench_rod",
        q=[x, y],
        qdot=[xd, yd],
        lagrangian=(xd**2 + yd**2) / 2 - G * y,
        constraints={"rod": x**2 + y**2 - 1},
    )


def floor() -> vcigen.Model:
    x, y, xd, yd = sp.symbols("x y xd yd")
    return vcigen.Model(
        name="bench_floor",
        q=[x, y],
        qdot=[xd, yd],
        lagrangian=(xd**2 + yd**2) / 2 - G * y,
        contacts={"floor": y},
    )


def main() -> None:
    sol = solve_ivp(
        lambda _t, y: [y[1], -G * math.sin(y[0])],
        (0.0, T),
        [THETA0, 0.0],
        method="DOP853",
        rtol=1e-13,
        atol=1e-14,
    )
    ref = np.array([math.sin(sol.y[0, -1]), -math.cos(sol.y[0, -1])])
    start = {"q0": [math.sin(THETA0), -math.cos(THETA0)], "v0": [0.0, 0.0], "t_end": T}
    rows = {}
    for rule in ("trapezoid", "lobatto3"):
        sim = vcigen.build(pendulum(), backend="c", rule=rule)
        rows[rule] = []
        for h in HS:
            err = float(np.abs(sim.simulate(h=h, **start).q[-1] - ref).max())
            wall = best_time(sim, {"h": h, **start})
            rows[rule].append((h, err, wall, wall / round(T / h)))
    print("pendulum on a rod, t = 2 (error of q against DOP853; wall time best of 5)")
    print("| h | trapezoid error | trapezoid s | lobatto3 error | lobatto3 s | lobatto3 / trapezoid |")
    print("|---|---|---|---|---|---|")
    for (h, et, wt, _), (_, el, wl, _) in zip(rows["trapezoid"], rows["lobatto3"]):
        print(f"| {h} | {et:.2e} | {wt:.2e} | {el:.2e} | {wl:.2e} | {wl / wt:.2f} |")
    for target in (1e-4, 1e-6, 1e-8):  # interpolated, or extrapolated along the last two runs (marked)
        (wt, nt), (wl, nl) = (at_error(rows[rule], target) for rule in ("trapezoid", "lobatto3"))
        print(
            f"at error {target:g}: trapezoid {wt:.2e} s{nt}, lobatto3 {wl:.2e} s{nl}; "
            f"trapezoid / lobatto3 {wt / wl:.1f}"
        )
    kw = {"q0": [0.0, 0.0], "v0": [1.0, 0.0], "h": 0.001, "t_end": T}
    walls = {
        rule: best_time(vcigen.build(floor(), backend="c", rule=rule), kw)
        for rule in ("trapezoid", "lobatto3")
    }
    print(
        f"sliding on a floor, h = 0.001, 2000 held steps: trapezoid {walls['trapezoid']:.2e} s (the held "
        f"straight-line step), lobatto3 {walls['lobatto3']:.2e} s (the general chain), ratio "
        f"{walls['lobatto3'] / walls['trapezoid']:.1f}"
    )


if __name__ == "__main__":
    main()
