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


@dataclass(frozen=True)
class Rule:
    """A quadrature rule for the action over one step."""

    name: str
    order: int
    symmetric: bool
    mean_lagrangian: Callable[[LagrangianFn, sp.Matrix, sp.Matrix, sp.Symbol], sp.Expr]
    paper: str


def _trapezoid(L: LagrangianFn, q0: sp.Matrix, v: sp.Matrix, h: sp.Symbol) -> sp.Expr:
    """``L_d = h/2 [L(q0, v) + L(q1, v)]``, ``q1 = q0 + h v``; eq. (71) for ``T - V``."""
    return (L(q0, v) + L(q0 + h * v, v)) / 2


def midpoint_rule(gamma: sp.Rational = sp.S.Half) -> Rule:
    """``L_d = h L((1 - gamma) q0 + gamma q1, v)``, eq. (57) (MATH.md fixes the weights)."""

    def ld(L: LagrangianFn, q0: sp.Matrix, v: sp.Matrix, h: sp.Symbol) -> sp.Expr:
        return L(q0 + gamma * h * v, v)

    order = 2 if gamma == sp.Rational(1, 2) else 1
    return Rule(
        name="midpoint" if gamma == sp.Rational(1, 2) else f"midpoint_{gamma}",
        order=order,
        symmetric=order == 2,
        mean_lagrangian=ld,
        paper="(57)",
    )


TRAPEZOID = Rule("trapezoid", order=2, symmetric=True, mean_lagrangian=_trapezoid, paper="(71)")
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
