"""Discrete Lagrangians ``L_d(q0, q1, h) ~ int_0^h L dt`` as data.

A rule gives the *mean Lagrangian* ``l(q0, v, h)`` over one step, with
``v = (q1 - q0)/h`` and ``L_d = h l``. Writing ``L_d`` through the segment
velocity ``v`` keeps every derived quantity polynomial in ``h`` (no division
by the step, so sub-steps ``alpha h -> 0`` are harmless; MATH.md,
*Conditioning*). Adding a rule is adding one entry to :data:`RULES`.

A rule may carry *internal points* (``stages > 0``): then ``L_d`` is an extremum
over them (a Galerkin discrete Lagrangian, Marsden & West 2001 §2.6) and the mean
Lagrangian takes one more argument, the internal points written in O(1) unknowns
``u`` (``n`` per stage) so that nothing divides by the step; their stationarity
``dl/du = 0`` is one more residual in every phase (vcigen.derive).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

import sympy as sp

# L(q, v) -> expression, with q and v sequences of expressions.
LagrangianFn = Callable[[Sequence[sp.Expr], Sequence[sp.Expr]], sp.Expr]
# F(q, v, t) -> the generalized force (a column), for the discrete forces of Lagrange-d'Alembert.
ForceFn = Callable[[sp.Matrix, sp.Matrix, sp.Expr], sp.Matrix]


@dataclass(frozen=True)
class Rule:
    """A quadrature rule for the action over one step."""

    name: str
    order: int
    symmetric: bool
    mean_lagrangian: Callable[[LagrangianFn, sp.Matrix, sp.Matrix, sp.Symbol], sp.Expr]
    paper: str
    # (F, q0, v, tau, t0) -> (f_d-, f_d+): the discrete forces at the segment's two ends (MATH.md, Forcing),
    # the rule's own quadrature of int F . dq over the segment.
    discrete_forces: Callable[..., tuple[sp.Matrix, sp.Matrix]] | None = None
    # internal points (each in R^n): mean_lagrangian(L, q0, v, h, u) with u the n * stages O(1) unknowns
    stages: int = 0
    # A rule with internal points: (F, q0, v, tau, t0, u) -> StagedForces (discrete_forces stays None).
    staged_forces: Callable[..., StagedForces] | None = None
    # The internal points' places: q_m,k = q0 + h (nodes[k] v + u_k), one fraction per stage (the constrained
    # step holds them on the active rows; vcigen.derive.sustained_routines).
    nodes: tuple[sp.Rational, ...] = ()
    # The weight of the segment's start node in its quadrature: the constrained step's start impulse is
    # Lam ~ end_weight h lambda (trapezoid: h/2; lobatto3: h/6), read back as a force at an impact.
    end_weight: sp.Rational = sp.S.Half

    @property
    def lam_rate(self) -> float:
        """``1/end_weight``: the constrained step's start impulse ``Lam`` times ``lam_rate/h`` is a force."""
        return float(1 / self.end_weight)

    @property
    def inner_ratio(self) -> float:
        """Each internal point's multipliers ``Lam_m`` per start impulse ``Lam`` (the Newton's start):
        ``(1 - 2 w)/(w stages)``, ``w = end_weight`` (lobatto3: 4; no internal points: 0)."""
        return float((1 - 2 * self.end_weight) / (self.end_weight * max(self.stages, 1)))


@dataclass(frozen=True)
class StagedForces:
    """Discrete Lagrange-d'Alembert forces of a rule with internal points (MATH.md *Forcing*), in the
    segment's unknowns ``(q0, v, u)``.

    ``stage`` is the force on the internal points: their stationarity reads ``dl/du + stage = 0``.
    ``minus``, ``plus`` are ``f_d-``, ``f_d+`` at the ends *with the internal points' share* (the chain rule
    from the nodes ``(q0, q_m, q1)`` to ``(q0, v, u)`` with the stationarity substituted), so that
    ``p- = l_v - tau l_q0 - minus`` and ``p+ = l_v + plus``. ``energy`` corrects ``E_d = v . l_v - l - tau
    l_tau`` to ``-D3 L_d`` at fixed nodes (the term ``u . l_u`` with ``l_u = -stage``). ``start`` and
    ``end`` are the quadratures of the time component ``F_t = -F . qdot`` (37) against the variation of the
    start and end times (``delta t(s) = (1 - s) delta t0``, ``s delta t1`` at fixed nodes), with the sign
    that makes the energy at the segment's start ``E_d - start`` and at its end ``E_d + end``; ``end +
    start`` is the rule's quadrature of the work ``int F . qdot dt`` over the segment.
    """

    minus: Any
    plus: Any
    stage: Any
    energy: Any
    start: Any
    end: Any


def _trapezoid(L: LagrangianFn, q0: sp.Matrix, v: sp.Matrix, h: sp.Symbol) -> sp.Expr:
    """``L_d = h/2 [L(q0, v) + L(q1, v)]``, ``q1 = q0 + h v``; eq. (71) for ``T - V``."""
    return (L(q0, v) + L(q0 + h * v, v)) / 2


def _trapezoid_forces(F: ForceFn, q0: sp.Matrix, v: sp.Matrix, h: sp.Symbol, t0: sp.Expr):
    """``f_d- = h/2 F(q0, v, t0)``, ``f_d+ = h/2 F(q1, v, t0 + h)`` (the trapezoid at each end)."""
    return h / 2 * F(q0, v, t0), h / 2 * F(q0 + h * v, v, t0 + h)


def midpoint_rule(gamma: sp.Rational = sp.S.Half) -> Rule:
    """``L_d = h L((1 - gamma) q0 + gamma q1, v)``, eq. (57) (MATH.md fixes the weights)."""

    def ld(L: LagrangianFn, q0: sp.Matrix, v: sp.Matrix, h: sp.Symbol) -> sp.Expr:
        return L(q0 + gamma * h * v, v)

    def forces(F: ForceFn, q0: sp.Matrix, v: sp.Matrix, h: sp.Symbol, t0: sp.Expr):
        f = h * F(q0 + gamma * h * v, v, t0 + gamma * h)
        return (1 - gamma) * f, gamma * f

    order = 2 if gamma == sp.Rational(1, 2) else 1
    return Rule(
        name="midpoint" if gamma == sp.Rational(1, 2) else f"midpoint_{gamma}",
        order=order,
        symmetric=order == 2,
        mean_lagrangian=ld,
        paper="(57)",
        discrete_forces=forces,
    )


TRAPEZOID = Rule(
    "trapezoid",
    order=2,
    symmetric=True,
    mean_lagrangian=_trapezoid,
    paper="(71)",
    discrete_forces=_trapezoid_forces,
)
MIDPOINT = midpoint_rule()


def _lobatto3(L: LagrangianFn, q0: sp.Matrix, v: sp.Matrix, h: sp.Symbol, u: sp.Matrix) -> sp.Expr:
    """``L_d = h/6 [L(q0, qdot_0) + 4 L(q_m, qdot_1/2) + L(q1, qdot_1)]`` on the quadratic through
    ``q0, q_m, q1`` (MATH.md *Higher order*; Lobatto IIIA-IIIB, order 4).

    The internal point is ``q_m = q0 + h (v/2 + u)``: ``u = (q_m - (q0 + q1)/2)/h`` stays O(h), and the
    quadratic ``q(s) = q0 + s h v + 4 s (1 - s) h u`` has ``q'(s)/h = v + 4 (1 - 2 s) u``: the velocities
    ``v + 4u``, ``v``, ``v - 4u`` at ``s = 0, 1/2, 1``. The stationarity ``dl/du`` is
    ``(2/3) [L_v(q0, v + 4u) - L_v(q1, v - 4u) + h L_q(q_m, v)]``, with an O(1) Jacobian ``~ (4/3) 2 M`` in
    ``u`` even at ``h = 0`` (no division by a sub-step, none of a singular Jacobian either).
    """
    qm = q0 + h * (v / 2 + u)
    return (L(q0, v + 4 * u) + 4 * L(qm, v) + L(q0 + h * v, v - 4 * u)) / 6


def _lobatto3_forces(F: ForceFn, q0: sp.Matrix, v: sp.Matrix, h: sp.Symbol, t0: sp.Expr, u: sp.Matrix):
    """Lobatto quadrature of the virtual work ``int F . delta q dt`` over the quadratic ``q(s)`` of
    :func:`_lobatto3`: node forces ``h/6 F_0``, ``4h/6 F_m``, ``h/6 F_1`` on ``q0, q_m, q1`` (the Lagrange
    basis is 1 at its own node, 0 at the others), each ``F`` at its node's position, velocity
    (``v + 4u``, ``v``, ``v - 4u``) and time (``t0``, ``t0 + h/2``, ``t0 + h``).

    With ``u = (q_m - (q0 + q1)/2)/h``: ``dl/du = dL_d/dq_m``, so the stationarity gains ``f_m = 4h/6 F_m``;
    ``-D1 L_d = l_v - h l_q0 + l_u/2`` and ``D2 L_d = l_v - l_u/2`` at fixed ``q_m``, so with ``l_u = -f_m``
    each end takes half of ``f_m``; ``-D3 L_d = v . l_v + u . l_u - l - h l_h`` at fixed nodes.
    """
    f0 = F(q0, v + 4 * u, t0)
    fm = F(q0 + h * (v / 2 + u), v, t0 + h / 2)
    f1 = F(q0 + h * v, v - 4 * u, t0 + h)
    stage = sp.Rational(2, 3) * h * fm
    minus = h / 6 * f0 + stage / 2
    plus = h / 6 * f1 + stage / 2
    # time component F_t = -F . qdot at each node, weights h/6 (4h/6, h/6) times delta t(s) = 1 - s (s)
    wm = (fm.T * v)[0]
    start = h / 6 * ((f0.T * (v + 4 * u))[0] + 2 * wm)
    end = h / 6 * (2 * wm + (f1.T * (v - 4 * u))[0])
    return StagedForces(minus, plus, stage, -(u.T * stage)[0], start, end)


LOBATTO3 = Rule(
    "lobatto3",
    order=4,
    symmetric=True,
    mean_lagrangian=_lobatto3,
    paper="(Marsden-West 2001, 2.6)",
    stages=1,
    staged_forces=_lobatto3_forces,
    nodes=(sp.S.Half,),
    end_weight=sp.Rational(1, 6),
)

RULES: dict[str, Rule] = {r.name: r for r in (TRAPEZOID, MIDPOINT, LOBATTO3)}
# The rules `vcigen generate --all` writes into generated/ (every example has every feature under them);
# lobatto3 on demand (`--rule lobatto3`, build(backend="c")): forces, constraints, sustained contact; no
# friction.
C_RULES: tuple[str, ...] = ("trapezoid", "midpoint")


def get_rule(rule: str | Rule) -> Rule:
    """Look a rule up by name; a :class:`Rule` passes through."""
    if isinstance(rule, Rule):
        return rule
    try:
        return RULES[rule]
    except KeyError:
        raise ValueError(f"unknown rule {rule!r}; choose one of {sorted(RULES)}") from None
