"""Dependent stick rows of cone contacts: the tangential forces' free split and its Coulomb margin.

Two cone contacts of one body sticking at once (a rod lying on two rough points of a 3-D floor) hold more
stick rows than the body has free coordinates: with both normal rows held, the four stick rows of the rod's
ends span 3 directions, so one of them is *dependent* (``SustainedSteps._stick``) and is not held. The forces
of the rows that are held are then unique, but the contacts' tangential forces are not: every multiple of the
*null combination* ``n`` (``sum_r n_r grad psi_r = 0``, ``n = -1`` on the dependent row) can be added to
them (the rod: equal and opposite forces along its axis). Coulomb's law asks for *some* split inside every
cone, so the margin of the coupled cones is

    m = max_alpha min_c ( mu_c N_c - |F_c + alpha d_c| ),

``F_c`` the stick forces of cone ``c``'s two rows, ``d_c`` the null combination on them and ``N_c`` its
normal force: the stick holds while ``m >= 0``. Each term is concave in ``alpha``, so their minimum is; its
maximiser lies between the terms' own maximisers ``-F_c . d_c / |d_c|^2`` and is found by bisection on the
sign of the least term's slope (:func:`split`), to the last bit: at most ``SPLIT_ITER`` halvings, ending
where the bracket no longer moves (every later halving would leave it so). Exact when
``n`` has no part on the normal rows (a flat floor); a normal part is not shifted.

Pure NumPy; ``templates/sustained_cone_split.c.j2`` has the same functions (``null_combination``, ``split``).
"""

from __future__ import annotations

import math

import numpy as np

SPLIT_ITER = 100  # bisection halvings of the split's bracket


def null_combination(grad: np.ndarray, act: np.ndarray, row: int) -> np.ndarray:
    """``n`` over every row with ``sum_r n_r grad_r = 0``: ``-1`` on ``row`` (a dependent stick row), on the
    active rows the coefficients of ``grad[row]`` in their gradients (normal equations; the active rows are
    independent), 0 elsewhere."""
    rows = np.flatnonzero(act)
    a = grad[rows]
    n = np.zeros(grad.shape[0])
    n[rows] = np.linalg.solve(a @ a.T, a @ grad[row])
    n[row] = -1.0
    return n


def _term(cap: float, force, d, alpha: float) -> tuple[float, float]:
    """``cap - |F + alpha d|`` and its slope in ``alpha`` (0 where ``F + alpha d = 0``)."""
    x, y = force[0] + alpha * d[0], force[1] + alpha * d[1]
    norm = math.hypot(x, y)
    return cap - norm, (-(d[0] * x + d[1] * y) / norm if norm > 0.0 else 0.0)


def split(caps, forces, dirs) -> tuple[float, float, list[float]]:
    """``max_alpha min_c (caps_c - |forces_c + alpha dirs_c|)``: ``(margin, alpha, each term at alpha)``.

    Bisection on ``[min, max]`` of the terms' maximisers ``-F_c . d_c / |d_c|^2``: the least term's slope
    says on which side the maximiser of the (concave) minimum lies."""
    lo, hi = math.inf, -math.inf
    for force, d in zip(forces, dirs):
        dd = d[0] * d[0] + d[1] * d[1]
        if dd > 0.0:
            a = -(force[0] * d[0] + force[1] * d[1]) / dd
            lo, hi = min(lo, a), max(hi, a)
    if lo > hi:
        lo = hi = 0.0
    for _ in range(SPLIT_ITER):  # until the bracket stops moving (then every later halving is the same)
        mid = 0.5 * (lo + hi)
        least, slope = math.inf, 0.0
        for cap, force, d in zip(caps, forces, dirs):  # _term, inline (the slope of the least term only)
            x, y = force[0] + mid * d[0], force[1] + mid * d[1]
            norm = math.hypot(x, y)
            if cap - norm < least:
                least, slope = cap - norm, (-(d[0] * x + d[1] * y) / norm if norm > 0.0 else 0.0)
        if slope > 0.0:
            if mid == lo:
                break
            lo = mid
        else:
            if mid == hi:
                break
            hi = mid
    alpha = 0.5 * (lo + hi)
    values = [_term(cap, force, d, alpha)[0] for cap, force, d in zip(caps, forces, dirs)]
    return min(values), alpha, values
