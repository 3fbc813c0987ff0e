"""The held grid step run by the Python stepper (:class:`HeldSteps`, :func:`held_step`, :func:`closed_step`)
on the routines of :mod:`vcigen.held` (whose docstring gives the algorithm). The C loop
(``<model>_held_glide`` in ``templates/sustained_held_glide.c.j2``) and :func:`held_step` are one algorithm;
a step whose end shows an event, whose solve does not converge or whose state is not finite is not taken
(``None``): the general chain (:mod:`vcigen.sustained`) takes it from the same start.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from .held_circle import Carry
from .held_roots import EPS_LIFT, REACH

HELD_ITER = 8  # Newton iterations of the held step at most (then the general chain takes the step)

ABSTOL, ABSTOL_STEP = 1e-13, 1e-15  # the general Newton's (backends.ccontext.NEWTON)


def factor_small(a: np.ndarray):
    """``a`` factored for :func:`apply_small` (the C ``<model>_held_factor``): for 1 and 2 unknowns its
    inverse in closed form, above ``a`` itself (solved by LU); ``None`` if singular."""
    na = a.shape[0]
    if na == 1:
        return None if not a[0, 0] != 0.0 else np.array([[1.0 / a[0, 0]]])
    if na == 2:
        det = a[0, 0] * a[1, 1] - a[0, 1] * a[1, 0]
        if not det != 0.0:
            return None
        inv = 1.0 / det
        return np.array([[a[1, 1] * inv, -a[0, 1] * inv], [-a[1, 0] * inv, a[0, 0] * inv]])
    return None if np.linalg.matrix_rank(a) < na else a


def apply_small(f: np.ndarray, b: np.ndarray) -> np.ndarray:
    """The solution of ``a x = b`` from ``f = factor_small(a)`` (the C ``<model>_held_apply``)."""
    if len(b) == 1:
        return np.array([b[0] * f[0, 0]])
    if len(b) == 2:
        return np.array([f[0, 0] * b[0] + f[0, 1] * b[1], f[1, 0] * b[0] + f[1, 1] * b[1]])
    return np.linalg.solve(f, b)


def all_finite(energy: float, forces: np.ndarray, q1: np.ndarray, p1: np.ndarray) -> bool:
    """Whether ``E_d``, the active rows' forces, ``q1`` and ``p1`` are all finite, by one test of their sum in
    the C loop's order: a sum of finite values is not finite only past ~1e307 (then the general chain takes
    the step, as for a non-finite value)."""
    total = energy
    for f in forces:
        total += float(f)
    for a, b in zip(q1, p1):
        total += float(a)
        total += float(b)
    return bool(np.isfinite(total))


def one_row_clears(k, kc, row: int, act, q, p, q1, p1, energy: float, force: float, res: float,
                   residual: float, phi_tol: float) -> bool:  # fmt: skip
    """The tests of a closed step on one row (:func:`closed_step`, ``vcigen.held_circle.circle_step``; C:
    ``<model>_held_closed_step``, ``<model>_held_circle_one``): the residual ``res`` within
    ``residual (1 + |p|)``, no lift-off (``force`` not below ``-EPS_LIFT (1 + |force|)`` on a contact row),
    no inactive row crossed or within the step's reach (:func:`idle_near`), ``E_d``, the force, ``q1`` and
    ``p1`` finite."""
    if not abs(res) <= residual * (1.0 + float(np.max(np.abs(p)))):
        return False
    if not k.row_bilateral[row] and force < -EPS_LIFT * (1.0 + abs(force)):
        return False  # a lift-off inside the step
    if k.r > 1:
        psi, grad, _ = k.held_rows(q1, kc)
        if any(psi[r] < -phi_tol for r in range(k.r) if not act[r]):
            return False  # an inactive row crossed
        if idle_near(k, act, q, q1, psi, grad):
            return False  # an inactive row within the step's reach: the chain tests it for a dip
    return all_finite(energy, [force], q1, p1)


def idle_near(k, act, q, q1, psi, grad) -> bool:
    """Does an inactive contact row end within ``REACH`` times the step's move of 0: ``psi_r(q1)^2 < REACH^2
    |grad psi_r(q1)|^2 |q1 - q|^2``? Both ends admissible, the row may dip below 0 inside the step (a rod's
    bob across the corner its circle cuts off a wall: 0 at the start, 0.0045 at the end, the step's move
    0.16); the chain takes the step then and tests for a dip (``SustainedSteps._row_dips``). Sums in the C
    loop's order."""
    dq2 = 0.0
    for i in range(k.n):
        dq2 += (q1[i] - q[i]) * (q1[i] - q[i])
    for r in range(k.r):
        if act[r] or k.row_stick[r] >= 0:
            continue
        g2 = 0.0
        for i in range(k.n):
            g2 += grad[r, i] * grad[r, i]
        if psi[r] * psi[r] < REACH * REACH * g2 * dq2:
            return True
    return False


class Held(NamedTuple):
    """A held grid step that cleared its tests: the end state and what the step books."""

    q1: np.ndarray
    p1: np.ndarray
    v: np.ndarray
    lam: np.ndarray  # Lam per row (0 off the active rows)
    lam1: np.ndarray  # Lam' per row
    energy: float


def closed_carried(k, q, p, w, row: int, act, h: float, residual: float, phi_tol: float):
    """:func:`held_step` on one active row with a closed form (:func:`closed_forms`; C:
    ``<model>_held_closed_one``, the body of ``<model>_held_closed_loop``): the root of the row's quadratic
    along the line (``held_closed``), then the segment, the projection, the force and the residual
    (``held_root_end``) and the tests of ``held_step`` in the same order: ``(Held, w1)``, or ``None`` where
    the root does not hold (``B <= 0`` or ``D < 0``) or a test fails.

    ``w = (pc, lp)``: the momentum the line starts from and the ``Lam'`` it is short of ``p`` by (``pc = p +
    G^T lp``, ``G`` the row's gradient at ``q``), the previous step's ``w1``: its ``p+`` before the projection
    and that projection's ``Lam'``; ``None``: ``(p, 0)``. The root absorbs a move of the line along ``G``
    (RATTLE's ``Lam`` by ``lp``), so the step is the one from ``(q, p)`` to round-off, with the projection off
    the state's chain in the C loop, which carries ``w``; ``Lam`` is the root's less ``lp``.
    """
    kc = k.held_consts(h)
    m, e, f, s, _, _, a2, g, _ = k.held_root_dir(q, kc)
    pc, lp = (p, 0.0) if w is None else (w[:-1], float(w[-1]))
    v0, a, nu, slope, disc = k.held_root(q, pc, m, s, a2, kc)
    if not (slope[row] > 0.0 and disc[row] >= 0.0):
        return None
    n, at = len(q), row * len(q)
    v = v0 + nu[row] * f[at : at + n]  # the C loop's operations: a product, then a sum
    q1 = a + nu[row] * e[at : at + n]
    p_plus, energy = k.held_segment(q, v, kc)
    _, _, _, _, y, w_, _, _, iw = k.held_root_dir(q1, kc)
    p1, lam1_r, force, res = k.held_root_end(q1, p_plus, y, w_, iw, kc)
    p1 = p1[row]
    if not one_row_clears(
        k, kc, row, act, q, p, q1, p1, float(energy), float(force[row]), float(res[row]), residual, phi_tol
    ):
        return None
    lam, lam1 = np.zeros(k.r), np.zeros(k.r)
    lam[row], lam1[row] = nu[row] * g[row] - lp, lam1_r[row]
    return Held(q1, p1, v, lam, lam1, float(energy)), np.r_[p_plus, lam1_r[row]]


def closed_step(k, q, p, row: int, act, h: float, residual: float, phi_tol: float) -> Held | None:
    """:func:`closed_carried` from ``(p, 0)``: the closed step from ``(q, p)`` alone."""
    got = closed_carried(k, q, p, None, row, act, h, residual, phi_tol)
    return None if got is None else got[0]


def held_step(k, q, p, lam_in, act, h: float, residual: float, phi_tol: float) -> Held | None:
    """One held grid step from ``(q, p)`` (the C ``<model>_held_step``), or ``None`` if it does not clear.

    ``k``: the kernels (``held_consts``, ``held_free``, ``held_rows``, ``held_segment``, ``held_end``);
    ``lam_in``: the previous step's multipliers (the Newton start); ``act``: the active rows;
    ``residual``: ``Tolerances.residual`` (the accepted residual, relative to ``1 + |p|``), ``phi_tol``:
    ``Tolerances.phi`` (an inactive row below ``-phi_tol`` is crossed).
    """
    rows = [int(r) for r in np.flatnonzero(act)]
    if len(rows) == 1 and k.held_closed[rows[0]]:
        return closed_step(k, q, p, rows[0], act, h, residual, phi_tol)
    kc = k.held_consts(h)
    v0, jinv = k.held_free(q, p, kc)
    g0 = k.held_rows(q, kc)[1][rows]
    x = np.array([lam_in[r] for r in rows])

    def evaluate(x):
        v = v0 + jinv * (g0.T @ x)
        q1 = q + h * v
        psi, grad, hess = k.held_rows(q1, kc)
        res = float(np.max(np.abs(psi[rows]))) if np.isfinite(psi[rows]).all() else np.nan
        return v, q1, psi, grad, hess, res

    v, q1, psi, grad, hess, res = evaluate(x)
    for _ in range(HELD_ITER):
        if res <= ABSTOL or not res == res:
            break
        jac = factor_small(grad[rows] @ ((h * jinv)[:, None] * g0.T))
        if jac is None:
            break
        d = apply_small(jac, psi[rows])
        if np.max(np.abs(d)) <= ABSTOL_STEP:
            break
        x = x - d
        v, q1, psi, grad, hess, res = evaluate(x)
    if not res <= residual * (1.0 + float(np.max(np.abs(p)))):
        return None
    p_plus, energy = k.held_segment(q, v, kc)
    acc, minv = k.held_end(q1, kc)
    g1 = grad[rows]
    w = factor_small(g1 @ (minv[:, None] * g1.T))  # the Delassus matrix, the projection's and the forces'
    if w is None:
        return None
    lam1_a = apply_small(w, -(g1 @ (minv * p_plus)))
    u1 = minv * p_plus + minv * (g1.T @ lam1_a)
    p1 = p_plus + g1.T @ lam1_a
    curv = np.zeros(len(rows))
    for a, r in enumerate(rows):  # u1 . Hess psi_r . u1 on the pattern, in its order (as the C loop)
        for m, (i, j, wgt) in enumerate(k.held_pattern):
            curv[a] += wgt * u1[i] * hess[r, m] * u1[j]
    f_a = apply_small(w, -(g1 @ acc + curv))
    forces = np.zeros(k.r)
    forces[rows] = f_a
    f_eps = EPS_LIFT * (1.0 + float(np.max(np.abs(forces))))
    unilateral = [r for r in rows if not k.row_bilateral[r]]
    if any(forces[r] < -f_eps for r in unilateral):
        return None  # a lift-off inside the step
    idle = [r for r in range(k.r) if not act[r]]
    if any(psi[r] < -phi_tol for r in idle):
        return None  # an inactive row crossed
    if idle_near(k, act, q, q1, psi, grad):
        return None  # an inactive row within the step's reach: the chain tests it for a dip
    if not all_finite(float(energy), f_a, q1, p1):
        return None
    lam, lam1 = np.zeros(k.r), np.zeros(k.r)
    lam[rows], lam1[rows] = x, lam1_a
    return Held(q1, p1, v, lam, lam1, float(energy))


class HeldSteps:
    """The held grid step in :class:`~vcigen.stepper.Stepper` (the C loop's ``<model>_held_glide``)."""

    _carry = None  # the last rotation or closed step's hand-over (held_circle.Carry), as the C loop's

    def _held_step(self, h: float, q, p):
        """A held grid step from ``(q, p)`` if the kernels have it and it clears its tests, else ``None``.

        Taken, it books what ``SustainedSteps._chain`` books for a segment with no event: the impulses
        ``Lam + Lam'`` as the step's forces and ``Lam`` as the next step's Newton start.
        """
        k = self.k
        if not getattr(k, "held", False):
            return None
        rows = np.flatnonzero(self.act)
        circle = len(rows) == 1 and any(getattr(k, "held_circle", ())) and k.held_closed[rows[0]]
        circle = circle and k.held_circle[rows[0]]  # a rotation is a closed step (off with it)
        closed = len(rows) == 1 and k.held_closed[rows[0]] and getattr(k, "closed_carried", False)
        if circle or closed:  # the step as a rotation (vcigen.held_circle) or a closed step, w carried
            tol, c = self.tol, self._carry
            w = None if c is None or c.row != rows[0] else c.at(q, p, h, k.par)
            step = k.circle_step if circle else k.closed_step
            got = step(q, p, w, int(rows[0]), self.act, h, tol.residual, tol.phi)
            out = None if got is None else got[0]
            par = np.array(k.par, float)
            self._carry = None if got is None else Carry(out.q1, out.p1, h, par, got[1], int(rows[0]))
        else:
            out = k.held_step(q, p, self._lam, self.act, h, self.tol.residual, self.tol.phi)
        if out is None:
            return None
        self._chained = True
        if self._record_held:  # the tangent (vcigen.sensitivity.Tracker.held): u1 of M u1 = p1
            u1 = self._velocity(out.q1, out.v, out.p1)
            lam_m = np.zeros(0)  # no internal points (a rule with them has no held grid step)
            self._held_seg = (out.v, out.lam, out.lam1, lam_m, u1, self.act.copy())
        self._book(out.lam + out.lam1, out.q1)
        self._lam = np.where(self.act, out.lam * (self._h / h), 0.0)
        return out.q1, out.p1, out.energy, out.v
