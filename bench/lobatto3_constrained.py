"""Which constrained lobatto3 keeps order 4: a standalone prototype for the next step (bilateral constraints
and sustained contact under ``rule="lobatto3"``; README *Fourth order*, not yet in vcigen).

The Cartesian pendulum ``L = |qdot|^2/2 - g y``, ``x^2 + y^2 = 1``, ``theta(0) = 0.8`` at rest, under the
Galerkin-Lobatto ``L_d(q0, q_m, q1)`` in position-momentum form (RATTLE, MATH.md *Sustained contact*):
``p0 = -D1 L_d + lam0 grad g(q0)``, ``g(q1) = 0``, ``p1 = D2 L_d + lam1 grad g(q1)`` tangent, and either

* the internal point free: ``D_m L_d = 0`` (the impact phases' stationarity, unchanged), or
* the internal point on the constraint too: ``D_m L_d = lam_m grad g(q_m)``, ``g(q_m) = 0``.

Error of ``q`` at t = 2 against DOP853 (rtol 1e-13) on ``theta'' = -g sin theta``; no vcigen inside.
Run: ``python -m bench.lobatto3_constrained``.
"""

from __future__ import annotations

import math

import numpy as np
import sympy as sp
from scipy.integrate import solve_ivp

G, THETA0, T = 9.81, 0.8, 2.0


def _system(constrained: bool):
    h = sp.Symbol("h")
    q0, qm, q1 = (sp.Matrix(sp.symbols(f"x{s} y{s}")) for s in ("0", "m", "1"))
    p0 = sp.Matrix(sp.symbols("px py"))
    l0, lm = sp.symbols("l0 lm")

    def lag(q, v):
        return v.dot(v) / 2 - G * q[1]

    def grad(q):
        return sp.Matrix([2 * q[0], 2 * q[1]])

    def con(q):
        return q[0] ** 2 + q[1] ** 2 - 1

    v0, vm, v1 = (-3 * q0 + 4 * qm - q1) / h, (q1 - q0) / h, (q0 - 4 * qm + 3 * q1) / h
    ld = h / 6 * (lag(q0, v0) + 4 * lag(qm, vm) + lag(q1, v1))
    d1, dm, d2 = (sp.Matrix([ld.diff(s) for s in q]) for q in (q0, qm, q1))
    if constrained:
        x = [*q1, *qm, l0, lm]
        res = sp.Matrix([*(p0 + d1 + l0 * grad(q0)), *(dm - lm * grad(qm)), con(q1), con(qm)])
    else:
        x = [*q1, *qm, l0]
        res = sp.Matrix([*(p0 + d1 + l0 * grad(q0)), *dm, con(q1)])
    step = sp.lambdify([x, [*q0, *p0, h]], [res, res.jacobian(x)], "numpy")
    return step, sp.lambdify([[*q0, *qm, *q1, h]], d2, "numpy"), len(x)


def run(constrained: bool, h: float) -> np.ndarray:
    step, end, nx = _system(constrained)
    q, p = np.array([math.sin(THETA0), -math.cos(THETA0)]), np.zeros(2)
    for _ in range(round(T / h)):
        x = np.concatenate([q + h * p, q + h * p / 2, np.zeros(nx - 4)])
        for _ in range(50):
            r, jac = step(x, [*q, *p, h])
            dx = np.linalg.solve(np.asarray(jac, float), np.asarray(r, float).ravel())
            x -= dx
            if np.max(np.abs(dx)) < 1e-14:
                break
        q1 = x[:2]
        pp = np.asarray(end([*q, *x[2:4], *q1, h]), float).ravel()
        n = 2 * q1
        p, q = pp - pp.dot(n) / n.dot(n) * n, q1  # p1 tangent (M = I)
    return q


def main() -> None:
    sol = solve_ivp(
        lambda _t, y: [y[1], -G * math.sin(y[0])],
        (0.0, T),
        [THETA0, 0.0],
        method="DOP853",
        rtol=1e-13,
        atol=1e-13,
    )
    th = sol.y[0, -1]
    ref = np.array([math.sin(th), -math.cos(th)])
    hs = [0.1, 0.05, 0.025, 0.0125]
    for constrained in (False, True):
        errs = [float(np.max(np.abs(run(constrained, h) - ref))) for h in hs]
        orders = [math.log2(errs[i] / errs[i + 1]) for i in range(len(errs) - 1)]
        label = "internal point on the constraint" if constrained else "internal point free"
        shown = " ".join(f"{e:.2e}" for e in errs)
        print(f"{label:34s} errors {shown}  orders {' '.join(f'{o:.2f}' for o in orders)}")


if __name__ == "__main__":
    main()
