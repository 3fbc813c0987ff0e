"""SymPy -> C99 expressions for the generated sources.

A :class:`ArrayC99Printer` prints every input symbol of a routine as an array
entry (``q0[1]``, ``par[0]``) and every CSE temporary as a local ``double``.
Nothing the user typed reaches the C text except through this printer, so a
model cannot inject code; names in C are built from validated identifiers only.
"""

from __future__ import annotations

from collections.abc import Mapping

import sympy as sp
from sympy.printing.c import C99CodePrinter

from .. import csememo
from ..routines import Routine

# Integer powers up to this exponent are printed as products (exact, and fast without -ffast-math).
_MAX_PRODUCT_POWER = 4


class ArrayC99Printer(C99CodePrinter):
    """A C99 printer with symbols mapped to C lvalues (array entries or locals)."""

    def __init__(
        self, names: Mapping[sp.Symbol, str], sqrt_powers: bool = False, inverse_powers: bool = False
    ) -> None:
        super().__init__({"strict": False})
        # SymPy prints sqrt(2), pi/4, log(2), ... as M_SQRT2, M_PI_4, M_LN2: POSIX, not C99, undeclared under
        # -std=c99. Printed as the expressions they stand for (a model's friction tangent (x - y)/sqrt(2) did
        # not compile).
        self.math_macros = {}
        self._names = dict(names)
        self._sqrt_powers = sqrt_powers
        self._inverse_powers = inverse_powers

    def _print_Symbol(self, expr: sp.Symbol) -> str:
        try:
            return self._names[expr]
        except KeyError:
            raise ValueError(f"symbol {expr!r} is not an input of the routine being printed") from None

    _print_Dummy = _print_Symbol

    def _print_Pow(self, expr: sp.Pow) -> str:
        base, exp = expr.as_base_exp()
        if exp.is_Integer and 2 <= int(exp) <= _MAX_PRODUCT_POWER:
            b = self.parenthesize(base, 1000)  # always wrap non-atoms
            return "(" + "*".join([b] * int(exp)) + ")"
        if self._inverse_powers and exp.is_Integer and -_MAX_PRODUCT_POWER <= int(exp) <= -2:
            b = self.parenthesize(base, 1000)  # b^-k = 1/(b ... b): no pow (not bit for bit pow's)
            return "(1.0/(" + "*".join([b] * -int(exp)) + "))"
        odd = exp.is_Rational and exp.q == 2
        half = odd and (3 <= abs(exp.p) <= 2 * _MAX_PRODUCT_POWER + 1 or exp.p == -1)
        if self._sqrt_powers and half:
            b = self.parenthesize(base, 1000)  # b^(k/2) = b^((k-1)/2) sqrt(b): no pow (not bit for bit pow's)
            prod = "(" + "*".join([b] * ((abs(exp.p) - 1) // 2) + [f"sqrt({self._print(base)})"]) + ")"
            return prod if exp.p > 0 else f"(1.0/{prod})"
        return super()._print_Pow(expr)

    def _print_Pi(self, expr: sp.Basic) -> str:
        return self._print_Float(sp.Float(sp.pi, 17))  # M_PI is not C99

    def _print_Exp1(self, expr: sp.Basic) -> str:
        return self._print_Float(sp.Float(sp.E, 17))

    def _print_Float(self, expr: sp.Float) -> str:
        return repr(float(expr))

    def _print_sign(self, expr: sp.Basic) -> str:
        arg = self._print(expr.args[0])
        return f"(double)(({arg} > 0) - ({arg} < 0))"


def input_names(routine: Routine) -> dict[sp.Symbol, str]:
    """Each input symbol of ``routine`` -> ``<arg>[<i>]``."""
    return {s: f"{a.name}[{i}]" for a in routine.inputs for i, s in enumerate(a.symbols)}


# An output with more zero entries than this is zero-filled by a loop; only its nonzero entries are printed.
ZERO_FILL = 16


def print_routine_body(
    routine: Routine, sqrt_powers: bool = False, inverse_powers: bool = False, plain_cse: bool = False
) -> tuple[list[tuple[str, str]], list[list[tuple[int, str]]], list[tuple[int, int] | None]]:
    """CSE'd body of ``routine``: ``(temporaries, outputs, fills)``; with ``sqrt_powers``, half-integer powers
    ``b^(k/2)`` (``3 <= |k| <= 9``, and ``k = -1``) are printed as ``b^((|k|-1)/2) sqrt(b)`` (its inverse for
    ``k < 0``), without libm's ``pow``; with
    ``inverse_powers``, ``b^-k`` (``2 <= k <= 4``) as ``1/(b ... b)``; with ``plain_cse``, SymPy's CSE
    without its ``basic`` pre-optimisations (whose ``factor_terms`` takes minutes on the nested rational
    expressions of ``vcigen.backends.cheld_map``, for about the same operation count).

    ``temporaries`` are ``(name, C expression)`` in evaluation order; each output is a list of
    ``(flat index, C expression)`` of the entries this routine writes itself: those past the ones
    its :attr:`~vcigen.routines.Routine.head` computes, all of them (zeros too), unless the output
    has more than ``ZERO_FILL`` zeros: then ``fills`` gives ``(first, end)`` to zero-fill and only
    the nonzero entries are listed (a sparse Jacobian in O(nonzeros) lines).
    """
    names = input_names(routine)
    listed, fills = [], []
    for o, first in zip(routine.outputs, routine.head_sizes()):
        own = list(enumerate(o.expr.flat()))[first:]
        sparse = sum(1 for _, e in own if e == 0) > ZERO_FILL
        fills.append((first, o.size) if sparse else None)
        listed.append([(k, e) for k, e in own if not (sparse and e == 0)])
    flat = [e for entries in listed for _, e in entries]
    opt = None if plain_cse else "basic"
    repl, reduced = csememo.cse(flat, optimizations=opt)
    for sym, _ in repl:
        names[sym] = sym.name
    printer = ArrayC99Printer(names, sqrt_powers, inverse_powers)
    temps = [(sym.name, printer.doprint(expr)) for sym, expr in repl]
    outs, i = [], 0
    for entries in listed:
        outs.append([(k, printer.doprint(e)) for (k, _), e in zip(entries, reduced[i : i + len(entries)])])
        i += len(entries)
    return temps, outs, fills
