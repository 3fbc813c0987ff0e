"""The continuous Legendre transform inverted: the velocity ``v`` with ``dL/dqdot(q, v) = p`` (``Result.v``).

A derived routine of the model's ``legendre`` (``p = dL/dqdot``, ``M = d2L/dqdot2``), vectorised over the
grid. When ``M`` does not depend on ``qdot`` (``L`` quadratic in the velocities, every mechanical
Lagrangian) the inverse is exact in one linear solve, ``v = M(q)^-1 (p - dL/dqdot(q, 0))``; otherwise
Newton's method on ``dL/dqdot(q, v) - p`` from ``v = 0``, each step halved until the residual is finite
and no larger (so a step out of the Lagrangian's domain is cut back), to round-off. Both backends use it.
"""

from __future__ import annotations

import numpy as np
import sympy as sp

from .derive import DiscreteSystem

MAX_NEWTON = 100
MAX_HALVINGS = 60


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
        res = self._residual(q, v, p, par)
        for _ in range(1 if self.linear else MAX_NEWTON):
            mass = self._eval(self._mass, q, v, par, (self.n, self.n))
            step = np.linalg.solve(mass, -res[..., None])[..., 0]
            if self.linear:
                return v + step
            new_v, res = self._damped(q, v, p, par, step, res)
            if np.all(np.abs(new_v - v) <= 4 * np.finfo(float).eps * (1.0 + np.abs(new_v))):
                return new_v
            v = new_v
        return v

    def _residual(self, q, v, p, par) -> np.ndarray:
        with np.errstate(invalid="ignore", divide="ignore", over="ignore"):
            return self._eval(self._mom, q, v, par, (self.n,)) - p

    def _damped(self, q, v, p, par, step, res) -> tuple[np.ndarray, np.ndarray]:
        """``v + s step``, ``s = 1, 1/2, ...`` per row: the first whose residual is finite and no larger."""
        norm = np.abs(res).max(axis=1)
        scale = np.ones(len(v))
        for _ in range(MAX_HALVINGS):
            new_v = v + scale[:, None] * step
            new_res = self._residual(q, new_v, p, par)
            bad = ~(np.abs(new_res).max(axis=1) <= norm)
            if not bad.any():
                break
            scale[bad] *= 0.5
        return new_v, new_res

    def _eval(self, fn, q, v, par, shape) -> np.ndarray:
        """``fn`` at every row of ``(q, v)``: ``(N, *shape)``."""
        rows = q.shape[0]
        with np.errstate(invalid="ignore", divide="ignore", over="ignore"):
            out = fn(*q.T, *v.T, *par)
        flat = [np.broadcast_to(np.asarray(x, dtype=float), (rows,)) for row in out for x in row]
        return np.stack(flat, -1).reshape(rows, *shape)
