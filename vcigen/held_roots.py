"""What the phases of sustained contact share (:mod:`vcigen.sustained`, :mod:`vcigen.friction_modes`,
:mod:`vcigen.held_impacts`): their tolerances, a constrained segment's end (:class:`End`) and the Illinois
root finder that locates their events (a lift-off, a row crossed, a stop, a slide), whose steps
(:func:`illinois_point`, :func:`illinois_update`) also locate the contact time (47) in
:mod:`vcigen.impact_step`; and the rows' dependence test (:func:`span_add`)."""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

ROOT_EPS = 1e-14  # a row crossing is located where |psi| <= ROOT_EPS max|psi at the bracket ends|
LEAVE_FRACTIONS = (1e-3, 1e-6, 1e-9)  # where a row just hit is sought above it (_leave, _row_crossing)
LIFT_ITER = 60  # Illinois iterations locating a lift-off at most
EPS_LAM = 1e-14  # |Lam| below this (relative to 1 + |p|) is zero: no release for round-off
# A held row's force below -EPS_LIFT (1 + the largest held force) is a lift-off; above, round-off: a box
# at rest on a face holds three vertices, one with a force 0 in exact arithmetic (the load on the diagonal
# through the other two), whose round-off through the Delassus solve reached 6e-14 of the largest (CasADi;
# 2.5e-16 in C).
EPS_LIFT = 1e-12
SLIDE_EPS = 1e-12  # a sliding velocity below this (relative to 1 + |u|) is 0: the contact sticks
SLIDE_LEAVE = (
    1e-3,
    1e-6,
)  # fractions tried to leave s = 0 where a slip starts from rest (its stop's root there)
MAX_LAW_ROWS = 12  # rows one impulse law may involve (its complementarity problem is solved by enumeration)
# Isotropic cones slipping at once in one impulse law: block Gauss-Seidel sweeps (each cone's 1-D root with
# the others' impulses fixed) until no tangential impulse moves by more than SLIDE_TOL (1 + max |m|)
SLIDE_SWEEPS = 500  # four cones of a box landing flat and sliding, coupled through it: ~200
SLIDE_TOL = 1e-14
BRAKE = 2.0  # cones sliding slower than BRAKE tau (friction's rate on them) are aimed implicitly
DEP_EPS = 1e-9  # a stick row this close (relative) to the span of the active rows' gradients is dependent
STICK_CYCLES = 2  # slides from rest of one stick row in a step, each stopped at once, before it sticks on
JAM_CYCLES = 2  # landings of one row in a step after it lifted off before the held contacts stick (a jam)
LIFT_CYCLES = 2  # pulls of one row at an instant it lifted off and was met again at, before it is held on
LEAVE_STEPS = 2  # grid steps after a row's release in which a crossing moving away is no impact (_met_back)
BACK_CYCLES = 16  # such crossings of one row in a chain before the next is an impact again (_met_back)
BOUNCE_CYCLES = 4  # impacts of one row in a step's held chains before the next holds it (Zeno: a few)
RESTITUTION_BISECTIONS = 30  # halvings of the restitution kept where friction would raise the energy
ONTO_ITER = 2  # Gauss-Newton steps moving a segment's start onto its rows (SustainedSteps._onto_rows)
# A held segment whose root is spurious (the kinetic energy of its velocity above SPURIOUS times its
# start's plus what the forces give over it: a root far from the motion), or whose Newton fails while a
# contact slips, is halved, SPLITS times at most (SustainedSteps._split_segment). SPURIOUS = 4 is twice the
# bound of the exact motion under a constant force F with workless or dissipative rows and a constant M:
# T' <= F . u <= |F|_{M^-1} sqrt(2 T), so sqrt(T) <= sqrt(T0) + a / sqrt(2), a = tau |F|_{M^-1}, and
# T <= 2 T0 + a^2 = 2 (T0 + a^2/2), for the segment's mean velocity too (T is convex). The CasADi
# held-contact tests' segments stay below 1.2; a rough star's root with a pulling normal impulse near
# Painleve's boundary reached 6.6 (16 before stop 39)
SPLITS = 6
SPURIOUS = 4.0
# A held grid step (vcigen.held_step) is not taken where an inactive row ends within REACH times the step's
# move of 0 (psi_r(q1) < REACH |grad psi_r(q1)| |q1 - q|): a dip below 0 inside the step is possible there
# (a rod's bob across the corner its circle cuts off a wall), and the chain tests for it (_row_dips)
REACH = 2.0
# A held segment's piece that ends at an event within E_SHORT h of its start is too short for its own E_d (the
# velocity (q1 - q) / tau round-off's: a landing 1.0017e-13 h after an impact logged 2.6001 against the
# 2.5925 there, box_v_drops --seed 21, drop 183): the event logs the E_d at the piece's start where the chain
# knows it (its last event's, or its last impact's after it), as it does at a segment's start
E_SHORT = 1e-6


def span_add(basis: list, g) -> bool:
    """Adds ``g``'s residual against the orthonormal ``basis`` (modified Gram-Schmidt), normalised, to it;
    False, adding nothing, where that residual is within ``DEP_EPS`` of 0 relative to ``|g|``: ``g`` in their
    span (the rows' dependence tests, :func:`in_span`, ``impulse_law._spanned``)."""
    w = g.copy()
    for b in basis:
        w -= float(b @ w) * b
    nw = math.sqrt(float(w @ w))  # numpy.linalg.norm's own sum, without its overhead
    if nw <= DEP_EPS * math.sqrt(float(g @ g)):
        return False
    basis.append(w / nw)
    return True


def in_span(grad, rows, r: int) -> bool:
    """Is row ``r``'s gradient within ``DEP_EPS`` of the span of the rows ``rows`` (modified Gram-Schmidt
    over them in the order given, :func:`span_add`)? :meth:`FrictionModes._dependent` and
    :meth:`HeldImpacts._rides_after` (C ``dependent``, ``rides_after``)."""
    basis: list = []
    for i in rows:
        span_add(basis, grad[i])
    return not span_add(basis, grad[r])


def illinois_point(a: float, ga: float, b: float, gb: float) -> float:
    """The next point of Illinois regula falsi on ``[a, b]`` (``ga >= 0 > gb``): the secant's root, or the
    midpoint where that is not strictly inside (or where ``ga = gb``: both 0, in
    :func:`vcigen.friction._illinois_up`)."""
    c = (a * gb - b * ga) / (gb - ga) if gb != ga else 0.5 * (a + b)
    return c if a < c < b else 0.5 * (a + b)


def illinois_update(a: float, ga: float, b: float, gb: float, side: int, c: float, gc: float):
    """The bracket after ``g(c) = gc`` (``ga >= 0 > gb``): ``(a, ga, b, gb, side)``, ``c`` taking the end of
    its sign; the other end's value halved when the same end moved twice in a row (``side``: -1 the end ``b``
    moved last, 1 the end ``a``, 0 none yet)."""
    if gc < 0:
        return a, ga / 2 if side == -1 else ga, c, gc, -1
    return c, gc, b, gb / 2 if side == 1 else gb, 1


def illinois(
    value,
    ga: float,
    gb: float,
    tiny: float,
    width: float,
    iters: int,
    guess,
    lo: float = 0.0,
    hi: float = 1.0,
) -> float:
    """Illinois regula falsi for the root of ``value`` on ``[lo, hi]`` (``value(lo) = ga >= 0 > gb =
    g(hi)``).

    ``value(s, guess) -> (g(s), guess')`` evaluates the sub-step map at ``s`` from a warm guess. Returns
    the first ``s`` with ``|g(s)| <= tiny``, or else, once the bracket is narrower than ``width`` (or after
    ``iters`` evaluations), its end where ``g < 0``.
    """
    a, b, side, v = lo, hi, 0, guess
    for _ in range(iters):
        c = illinois_point(a, ga, b, gb)
        gc, v = value(c, v)
        a, ga, b, gb, side = illinois_update(a, ga, b, gb, side, c, gc)
        if abs(gc) <= tiny:
            return c
        if b - a <= width:
            break
    return b


def hermite_min(g0: float, g1: float, d0: float, d1: float) -> tuple[float, float]:
    """Minimum over ``[0, 1]`` of the cubic with ends ``g0, g1`` and slopes ``d0, d1``."""
    c = np.array([2 * g0 - 2 * g1 + d0 + d1, -3 * g0 + 3 * g1 - 2 * d0 - d1, d0, g0])
    crit = [r.real for r in np.roots(np.polyder(c)) if abs(r.imag) < 1e-12 and 0 < r.real < 1]
    s = min((0.0, 1.0, *crit), key=lambda x: np.polyval(c, x))
    return float(s), float(np.polyval(c, s))


class End(NamedTuple):
    """Evaluations at the end ``(q1, u1)`` of a constrained segment: rows, their gradients and curvatures,
    the free dynamics' right-hand side and the mass matrix."""

    psi: np.ndarray | None
    grad: np.ndarray
    curv: np.ndarray
    rhs: np.ndarray
    mass: np.ndarray
