"""Translate SymPy expressions into CasADi SX, one node type at a time."""

from __future__ import annotations

from collections.abc import Callable, Mapping

import casadi as ca
import sympy as sp

_UNARY: dict[type, Callable] = {
    sp.sin: ca.sin,
    sp.cos: ca.cos,
    sp.tan: ca.tan,
    sp.asin: ca.asin,
    sp.acos: ca.acos,
    sp.atan: ca.atan,
    sp.sinh: ca.sinh,
    sp.cosh: ca.cosh,
    sp.tanh: ca.tanh,
    sp.exp: ca.exp,
    sp.log: ca.log,
    sp.Abs: ca.fabs,
    sp.sign: ca.sign,
    sp.floor: ca.floor,
    sp.ceiling: ca.ceil,
}


def _fold(fn: Callable, args: list) -> ca.SX:
    out = args[0]
    for a in args[1:]:
        out = fn(out, a)
    return out


def to_casadi(expr: sp.Basic, env: Mapping[sp.Basic, ca.SX]) -> ca.SX:
    """Convert ``expr``; ``env`` maps every free symbol to an SX."""
    if expr in env:
        return env[expr]
    if expr.is_Number:
        return ca.SX(float(expr))
    if expr is sp.pi:
        return ca.SX(float(sp.pi))
    if expr is sp.E:
        return ca.SX(float(sp.E))
    if isinstance(expr, sp.Piecewise):
        out = ca.SX(float("nan"))
        for val, cond in reversed(expr.args):
            c = 1 if cond is sp.true else to_casadi(cond, env)
            out = ca.if_else(c, to_casadi(val, env), out)
        return out
    args = [to_casadi(a, env) for a in expr.args]
    if isinstance(expr, sp.Add):
        return _fold(lambda a, b: a + b, args)
    if isinstance(expr, sp.Mul):
        return _fold(lambda a, b: a * b, args)
    if isinstance(expr, sp.Pow):
        base, ex = expr.args
        if ex == sp.Rational(1, 2):
            return ca.sqrt(args[0])
        if ex.is_Integer:
            return ca.constpow(args[0], args[1]) if int(ex) >= 0 else 1 / ca.constpow(args[0], -args[1])
        return args[0] ** args[1]
    if type(expr) in _UNARY or expr.func in _UNARY:
        return _UNARY[expr.func](args[0])
    if isinstance(expr, sp.atan2):
        return ca.atan2(args[0], args[1])
    if isinstance(expr, sp.Min):
        return _fold(ca.fmin, args)
    if isinstance(expr, sp.Max):
        return _fold(ca.fmax, args)
    if isinstance(expr, sp.Heaviside):
        return ca.if_else(args[0] >= 0, 1.0, 0.0)
    if isinstance(expr, sp.core.relational.Relational):
        ops = {"<": ca.lt, "<=": ca.le, ">": ca.gt, ">=": ca.ge, "==": ca.eq, "!=": ca.ne}
        return ops[expr.rel_op](args[0], args[1])
    raise ValueError(
        f"vcigen cannot translate {expr.func.__name__} ({expr}) to CasADi; "
        "use elementary functions, Abs, sign, Min, Max or Piecewise"
    )
