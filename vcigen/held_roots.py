"""What the phases of sustained contact share (:mod:`vcigen.sustained`, :mod:`vcigen.friction_modes`,
:mod:`vcigen.held_impacts`): their tolerances, a constrained segment's end (:class:`End`) and the Illinois
root finder that locates their events (a lift-off, a row crossed, a stop, a slide) like the contact time
(47)."""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

ROOT_EPS = 1e-14  # a row crossing is located where |psi| <= ROOT_EPS max|psi at the bracket ends|
LIFT_ITER = 60  # Illinois iterations locating a lift-off at most
EPS_LAM = 1e-14  # |Lam| below this (relative to 1 + |p|) is zero: no release for round-off
SLIDE_EPS = 1e-12  # a sliding velocity below this (relative to 1 + |u|) is 0: the contact sticks
MAX_LAW_ROWS = 12  # rows one impulse law may involve (its complementarity problem is solved by enumeration)
BRAKE = 2.0  # cones sliding slower than BRAKE tau (friction's rate on them) are aimed implicitly
DEP_EPS = 1e-9  # a stick row this close (relative) to the span of the active rows' gradients is dependent


def illinois(value, ga: float, gb: float, tiny: float, width: float, iters: int, guess) -> float:
    """Illinois regula falsi for the root of ``value`` on ``[0, 1]`` (``value(0) = ga >= 0 > gb = value(1)``).

    ``value(s, guess) -> (g(s), guess')`` evaluates the sub-step map at ``s`` from a warm guess. Returns
    the first ``s`` with ``|g(s)| <= tiny``, or else, once the bracket is narrower than ``width`` (or after
    ``iters`` evaluations), its end where ``g < 0``.
    """
    a, b, side, v = 0.0, 1.0, 0, guess
    for _ in range(iters):
        c = (a * gb - b * ga) / (gb - ga)
        if not a < c < b:
            c = 0.5 * (a + b)
        gc, v = value(c, v)
        if gc < 0:
            b, gb = c, gc
            ga = ga / 2 if side == -1 else ga
            side = -1
        else:
            a, ga = c, gc
            gb = gb / 2 if side == 1 else gb
            side = 1
        if abs(gc) <= tiny:
            return c
        if b - a <= width:
            break
    return b


class End(NamedTuple):
    """Evaluations at the end ``(q1, u1)`` of a constrained segment: rows, their gradients and curvatures,
    the free dynamics' right-hand side and the mass matrix."""

    psi: np.ndarray | None
    grad: np.ndarray
    curv: np.ndarray
    rhs: np.ndarray
    mass: np.ndarray
