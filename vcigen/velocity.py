"""The continuous Legendre transform inverted: the velocity ``v`` with ``dL/dqdot(q, v) = p`` (``Result.v``).

A derived routine of the model's ``legendre`` (``p = dL/dqdot``, ``M = d2L/dqdot2``), vectorised over the
grid. When ``M`` does not depend on ``qdot`` (``L`` quadratic in the velocities, every mechanical
Lagrangian) the inverse is exact in one linear solve, ``v = M(q)^-1 (p - dL/dqdot(q, 0))``; otherwise
Newton's method on ``dL/dqdot(q, v) - p`` from there, to round-off. Both backends use it.
"""

from __future__ import annotations

import numpy as np
import sympy as sp

from .derive import DiscreteSystem

MAX_NEWTON = 50


class LegendreInverse:
    """``(q (N, n), p (N, n), par) -> v (N, n)`` for one derived system."""

    def __init__(self, system: DiscreteSystem) -> None:
        routine = system.routines["legendre"]
        q, v = routine.input("q").symbols, routine.input("v").symbols
        par = routine.input("par").symbols
        mom, mass = routine.output("momentum").expr, routine.output("mass").expr
        self.n = len(q)
        self.linear = not (mass.free_symbols & set(v))
        self._mom = sp.lambdify([*q, *v, *par], mom.tolist(), modules="numpy")
        self._mass = sp.lambdify([*q, *v, *par], mass.tolist(), modules="numpy")

    def __call__(self, q: np.ndarray, p: np.ndarray, par) -> np.ndarray:
        q, p = np.atleast_2d(np.asarray(q, dtype=float)), np.atleast_2d(np.asarray(p, dtype=float))
        v = np.zeros_like(p)
        for _ in range(1 if self.linear else MAX_NEWTON):
            res = self._eval(self._mom, q, v, par, (self.n,)) - p
            step = np.linalg.solve(self._eval(self._mass, q, v, par, (self.n, self.n)), -res[..., None])[
                ..., 0
            ]
            v = v + step
            if np.all(np.abs(step) <= 4 * np.finfo(float).eps * (1.0 + np.abs(v))):
                break
        return v

    def _eval(self, fn, q, v, par, shape) -> np.ndarray:
        """``fn`` at every row of ``(q, v)``: ``(N, *shape)``."""
        rows = q.shape[0]
        out = fn(*q.T, *v.T, *par)
        flat = [np.broadcast_to(np.asarray(x, dtype=float), (rows,)) for row in out for x in row]
        return np.stack(flat, -1).reshape(rows, *shape)
