"""The impulse law's complementarity problem by projected block Gauss-Seidel (:class:`vcigen.impulse_law.
ImpulseLaw`'s last resort before it leaves a landing cone's friction out; C ``law_pgs``): each contact's block
(its normal row and a cone's two stick rows) solved exactly with the others' impulses fixed, sweep after
sweep, until no impulse moves."""

from __future__ import annotations

import math

import numpy as np

from .friction import cone_slide

PGS_SWEEPS = 5000  # the cube's landings beside a lifting edge settle within ~2000
PGS_TOL = 1e-15  # an impulse that moves by less than this (relative to 1 + max |Lam|) has settled


def _cone_block(wc, r, mu: float) -> np.ndarray | None:
    """One cone's impulses ``(N, t1, t2)`` with the others' fixed: ``r`` its rows' ``g.qdot+ - target`` at
    ``0``, ``wc`` its 3x3 block of ``w``. Sticks where the stick is in the cone; none (0) where the normal
    impulse would be ``<= 0``; else Coulomb's sliding impulse (:func:`vcigen.friction.cone_slide` on the
    Schur complement on its stick rows); None where that has no root."""
    try:
        stick = np.linalg.solve(wc, -r)
    except np.linalg.LinAlgError:
        return None
    if stick[0] >= 0.0 and math.hypot(stick[1], stick[2]) <= mu * stick[0]:
        return stick
    a = -r[0] / wc[0, 0]
    if not a > 0.0:
        return np.zeros(3)
    bn = wc[0, 1:] / wc[0, 0]
    g = r[1:] + wc[1:, 0] * a
    h = wc[1:, 1:] - np.outer(wc[1:, 0], bn)
    m = cone_slide(g, h.ravel(), bn, mu, a)
    if m is None:
        return None
    return np.array([a - bn @ m, m[0], m[1]])


def pgs(w, b, cones, normals, equal) -> np.ndarray | None:
    """Impulses ``Lam`` of the law's rows with ``gap = w Lam - b`` (``g.qdot+ - target``): ``cones`` ``[(n, i,
    o, mu)]`` (a normal row and its cone's two stick rows: stick or slide, as :func:`_cone_block`),
    ``normals`` (rows of one sign: ``Lam >= 0``, ``gap >= 0``, one of the two 0), ``equal`` (``gap = 0``,
    ``Lam`` free: bilateral rows, stick rows of no cone). Projected block Gauss-Seidel from 0, the blocks in
    that order, until no impulse moves by ``PGS_TOL (1 + max |Lam|)``; None where a block has no solution
    or the sweeps do not settle in ``PGS_SWEEPS``. The caller checks the law's conditions on the result."""
    lam = np.zeros(len(b))
    for _ in range(PGS_SWEEPS):
        moved = 0.0
        for n, i, o, mu in cones:
            ix = [n, i, o]
            wc = w[np.ix_(ix, ix)]
            r = w[ix] @ lam - wc @ lam[ix] - b[ix]
            new = _cone_block(wc, r, mu)
            if new is None:
                return None
            moved = max(moved, float(np.max(np.abs(new - lam[ix]))))
            lam[ix] = new
        for r_ in normals:
            new = max(lam[r_] - (float(w[r_] @ lam) - b[r_]) / w[r_, r_], 0.0)
            moved, lam[r_] = max(moved, abs(new - lam[r_])), new
        for r_ in equal:
            new = lam[r_] - (float(w[r_] @ lam) - b[r_]) / w[r_, r_]
            moved, lam[r_] = max(moved, abs(new - lam[r_])), new
        if moved <= PGS_TOL * (1.0 + float(np.max(np.abs(lam)))):
            return lam
    return None
