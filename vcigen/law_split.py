"""Splits of an impulse law's impulses where its tight rows are dependent (a box landing flat on four rough
vertices): the velocity after is unique, the impulses are not (``G_T^T Lam_T`` is), and Coulomb's law asks
for a split inside every cone (:class:`vcigen.impulse_law.ImpulseLaw`; C ``least_split``, ``cone_fit``)."""

from __future__ import annotations

import math

import numpy as np

from .held_roots import DEP_EPS, span_add

FIT_SWEEPS = 400  # alternating projections (cone_fit); seed 7's rough cube landings settle within ~40
FIT_SHRINK = 1e-6  # the cones narrowed by this (relative) in the projections: a point inside the true ones


def least_split(g, w, b, tight, s=None) -> np.ndarray | None:
    """The impulses of the tight rows ``T`` (indices of the law's rows ``g``, ``w = g M^-1 g^T``) at their
    targets (``w Lam = b`` on ``T``) where their gradients are dependent: the least split, ``min |Lam|``:
    ``Lam = G_T G_I^T z``, ``I`` an independent subset of ``T`` (modified Gram-Schmidt), ``(A^T A) z =
    G_I G_I^T Lam_I``, ``A = G_T G_I^T``, ``Lam_I`` the impulses with ``I`` alone; then one step of
    iterative refinement (the same map on the residual ``b_I - w_IT Lam_T``): the normal equations cost
    ``cond(A)^2`` of round-off and the caller checks the targets to ``EPS_LAM`` (a landing's split failed
    that by 3e-14 against 1.3e-14: rough cube drop 140 of seed 7). A sufficient test of the cones (another
    split may fit where this one does not: :func:`fit`). With weights ``s`` the least ``sum (Lam_i /
    s_i)^2`` instead (the rows scaled by ``s``: :meth:`ImpulseLaw._impulse_law` weights each cone's stick
    rows by the square root of its room ``mu_f N`` in the first split, so the second splits along the
    loads). ``b`` one right-hand side or a column of them (``(n, k)``: one factorisation for all). None
    where singular; the caller checks ``T``'s targets (consistency)."""
    if s is not None:
        lam = least_split(g * s[:, None], w * np.outer(s, s), b * s, tight)
        return None if lam is None else lam * s
    basis: list = []
    ind = [i for i in tight if span_add(basis, g[i])]
    lam = np.zeros(b.shape)
    try:
        a = g[tight] @ g[ind].T
        wi, ata, gig = w[np.ix_(ind, ind)], a.T @ a, g[ind] @ g[ind].T
        lam[tight] = a @ np.linalg.solve(ata, gig @ np.linalg.solve(wi, b[ind]))
        r = b[ind] - w[np.ix_(ind, tight)] @ lam[tight]  # the residual of the targets: once more
        lam[tight] += a @ np.linalg.solve(ata, gig @ np.linalg.solve(wi, r))
    except np.linalg.LinAlgError:
        return None
    return lam


def fit(g, lam, tight, cones, nonneg, eps: float) -> np.ndarray | None:
    """From ``lam`` (a split of the tight rows' impulses, indices ``tight`` of the law's rows ``g``), one
    with the same ``G_T^T Lam_T`` inside the cones ``[(n, i, o, mu)]`` (a normal row and two stick rows:
    ``|(Lam_i, Lam_o)| <= mu Lam_n`` to ``eps``; ``Lam_n = 0`` where ``n`` is not tight) and with ``Lam_r >=
    -eps`` on the rows ``nonneg``; None where not found in ``FIT_SWEEPS`` (or a cone's stick row is not
    tight).

    Alternating projections (von Neumann) between the affine set ``{Lam_T : G_T^T Lam_T = G_T^T lam_T}``
    (``lam_T`` plus a point's part orthogonal to ``G_T``'s columns, Gram-Schmidt twice) and the convex set of
    the cones (second-order cones: closed form) and half-lines: they converge to a point of the intersection
    where it is not empty (the cube's three-cone landings beside lifting vertices, where the least split
    leaves a cone: drops 44, 47, 180 of seed 7). Each sweep ends on the affine set, so a sweep's point inside
    the cones to ``eps`` is a split of the law (every target and gap the same to round-off); the cones are
    narrowed by ``FIT_SHRINK`` in the projections, so that such a point is reached in finitely many sweeps."""
    nt = len(tight)
    pos = {r: k for k, r in enumerate(tight)}
    if any(i not in pos or o not in pos for _, i, o, _ in cones):
        return None
    blocks = [(pos.get(n, nt), pos[i], pos[o], mu) for n, i, o, mu in cones]  # nt: a normal impulse of 0
    halves = [pos[r] for r in nonneg]
    basis: list = []
    for col in np.asarray(g)[tight].T:  # range(G_T): the directions the split may not move along
        v = col.copy()
        for _ in range(2):  # twice: orthonormal to round-off even for nearly dependent columns
            for q in basis:
                v -= float(q @ v) * q
        nv = math.sqrt(float(v @ v))
        if nv > DEP_EPS * math.sqrt(float(col @ col)):
            basis.append(v / nv)
    x0 = np.append(np.asarray(lam, dtype=float)[tight], 0.0)
    x = x0.copy()
    for _ in range(FIT_SWEEPS):
        inside = all(math.hypot(x[i], x[o]) <= mu * x[n] + eps for n, i, o, mu in blocks)
        if inside and all(x[r] >= -eps for r in halves):
            out = np.array(lam, dtype=float)
            out[tight] = x[:nt]
            return out
        y = x.copy()
        for n, i, o, mu in blocks:
            m, t = mu * (1.0 - FIT_SHRINK), math.hypot(y[i], y[o])
            if t <= m * y[n]:
                continue
            if m * t <= -y[n]:  # in the polar cone: to the apex
                y[n] = y[i] = y[o] = 0.0
                continue
            a = (y[n] + m * t) / (1.0 + m * m)  # onto the cone's edge
            y[n], y[i], y[o] = a, y[i] * (m * a / t), y[o] * (m * a / t)
        for r in halves:
            y[r] = max(y[r], 0.0)
        d = y[:nt] - x0[:nt]
        for q in basis:
            d -= float(q @ d) * q
        x[:nt] = x0[:nt] + d
        x[nt] = 0.0
    return None
