"""Discrete Lagrangians ``L_d(q0, q1, h) ~ int_0^h L dt`` as data.

A rule gives the *mean Lagrangian* ``l(q0, v, h)`` over one step, with
``v = (q1 - q0)/h`` and ``L_d = h l``. Writing ``L_d`` through the segment
velocity ``v`` keeps every derived quantity polynomial in ``h`` (no division
by the step, so sub-steps ``alpha h -> 0`` are harmless; MATH.md,
*Conditioning*). Adding a rule is adding one entry to :data:`RULES`.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass

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

RULES: dict[str, Rule] = {r.name: r for r in (TRAPEZOID, MIDPOINT)}


def get_rule(rule: str | Rule) -> Rule:
    """Look a rule up by name; a :class:`Rule` passes through."""
    if isinstance(rule, Rule):
        return rule
    try:
        return RULES[rule]
    except KeyError:
        raise ValueError(f"unknown rule {rule!r}; choose one of {sorted(RULES)}") from None
