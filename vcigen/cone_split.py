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

One-tangent contacts coupled by a dependent stick row (a ladder between a rough floor and a rough wall: with
both normal rows held it turns about the corner, and both stick rows hold that one freedom) take the same
split along a line, :func:`split_line`, each term ``mu_c N_c(alpha) - |F_c + alpha d_c|`` with the normal
force shifted too, ``N_c(alpha) = N_c + alpha sum_r n_r`` over the contact's normal rows (the wall's
friction lifts the ladder off the floor): exact for one dependence. A contact without friction whose normal
rows ``n`` involves keeps ``N_c(alpha) >= 0``: its term is ``N_c(alpha)``.

Pure NumPy; ``templates/sustained_cone_split.c.j2`` has the same functions (``null_combination``, ``split``),
``templates/sustained_stick_split.c.j2`` ``split_line`` and ``line_turns``.
"""

from __future__ import annotations

import math

import numpy as np

SPLIT_ITER = 100  # bisection halvings of the split's bracket
LINE_WIDEN = 60  # doublings of a line split's bracket while its minimum still rises at an end (split_line)


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

    def slope(mid: float) -> float:
        least, out = math.inf, 0.0
        for cap, force, d in zip(caps, forces, dirs):  # _term, inline (the slope of the least term only)
            x, y = force[0] + mid * d[0], force[1] + mid * d[1]
            norm = math.hypot(x, y)
            if cap - norm < least:
                least, out = cap - norm, (-(d[0] * x + d[1] * y) / norm if norm > 0.0 else 0.0)
        return out

    alpha = _bisect(slope, lo, hi)
    values = [_term(cap, force, d, alpha)[0] for cap, force, d in zip(caps, forces, dirs)]
    return min(values), alpha, values


def _bisect(slope, lo: float, hi: float) -> float:
    """The maximiser of a concave function on ``[lo, hi]`` from the sign of ``slope`` (its least term's) at
    the midpoints, to the last bit: ``SPLIT_ITER`` halvings at most, ending where the bracket no longer
    moves (every later halving would leave it so)."""
    for _ in range(SPLIT_ITER):
        mid = 0.5 * (lo + hi)
        if slope(mid) > 0.0:
            if mid == lo:
                break
            lo = mid
        else:
            if mid == hi:
                break
            hi = mid
    return 0.5 * (lo + hi)


def _line_least(caps, slopes, forces, dirs, alpha: float) -> tuple[float, float]:
    """The least term ``caps_c + alpha slopes_c - |forces_c + alpha dirs_c|`` at ``alpha`` and its slope."""
    least, slope = math.inf, 0.0
    for cap, s, force, d in zip(caps, slopes, forces, dirs):
        x = force + alpha * d
        value = cap + alpha * s - abs(x)
        if value < least:
            least, slope = value, s - (d if x > 0.0 else -d if x < 0.0 else 0.0)
    return least, slope


def line_turns(caps, slopes, forces, dirs, alpha: float) -> bool:
    """Whether the least term of :func:`split_line` turns at ``alpha`` (its slope ``>= 0`` just left of it and
    ``<= 0`` just right, 1e-9 relative away): a maximum, not a jam's widest bracket, where it still rose."""
    w = 1e-9 * (1.0 + abs(alpha))
    return (
        _line_least(caps, slopes, forces, dirs, alpha - w)[1] >= 0.0
        and _line_least(caps, slopes, forces, dirs, alpha + w)[1] <= 0.0
    )


def split_line(caps, slopes, forces, dirs) -> tuple[float, float, list[float]]:
    """``max_alpha min_c (caps_c + alpha slopes_c - |forces_c + alpha dirs_c|)`` (one-tangent contacts, each
    a scalar force; a frictionless contact's term has ``forces_c = dirs_c = 0``): ``(margin, alpha, each term
    at alpha)``.

    Each term is concave, so their minimum is. Bisection on the least term's slope, as :func:`split`, on a
    bracket of the terms' kinks ``-F_c / d_c`` and the zeros of the caps that move, ``-caps_c / slopes_c``,
    widened (its width doubled, ``LINE_WIDEN`` times at most) while the minimum still rises past an end:
    where friction jams (every term rises one way) the margin is that of the widest bracket, large."""
    points = [-f / d for f, d in zip(forces, dirs) if d != 0.0]
    points += [-c / s for c, s in zip(caps, slopes) if s != 0.0]
    lo, hi = (min(points), max(points)) if points else (0.0, 0.0)
    width = max([hi - lo, 1.0] + [abs(f) for f in forces] + [abs(c) for c in caps])
    for _ in range(LINE_WIDEN):
        if _line_least(caps, slopes, forces, dirs, hi)[1] <= 0.0:
            break
        hi, width = hi + width, 2.0 * width
    for _ in range(LINE_WIDEN):
        if _line_least(caps, slopes, forces, dirs, lo)[1] >= 0.0:
            break
        lo, width = lo - width, 2.0 * width
    alpha = _bisect(lambda mid: _line_least(caps, slopes, forces, dirs, mid)[1], lo, hi)
    values = [cap + alpha * s - abs(f + alpha * d) for cap, s, f, d in zip(caps, slopes, forces, dirs)]
    return min(values), alpha, values
