"""The intermediate form between derivation and backends.

A :class:`Routine` is a named function from named input vectors to named
output arrays, all SymPy. Every backend (CasADi, C) consumes exactly this.
"""

from __future__ import annotations

from dataclasses import dataclass

import sympy as sp

from . import csememo, sympy_speed


@dataclass(frozen=True)
class Arg:
    """A named input vector of symbols."""

    name: str
    symbols: tuple[sp.Symbol, ...]

    @property
    def size(self) -> int:
        return len(self.symbols)


@dataclass(frozen=True)
class Output:
    """A named output array (row-major when flattened)."""

    name: str
    expr: sp.Matrix

    @property
    def shape(self) -> tuple[int, int]:
        return tuple(self.expr.shape)  # type: ignore[return-value]

    @property
    def size(self) -> int:
        return self.expr.shape[0] * self.expr.shape[1]


@dataclass(frozen=True)
class Routine:
    """Named inputs -> named outputs; the unit both backends compile."""

    name: str
    inputs: tuple[Arg, ...]
    outputs: tuple[Output, ...]
    doc: str = ""
    # A routine with the same inputs whose outputs are the leading entries of some of these (same names):
    # the per-contact routines share it (the momentum rows of (47), (78) and their Jacobian), so a
    # backend may evaluate it once in code and print only the rows of this routine's own.
    head: Routine | None = None

    def input(self, name: str) -> Arg:
        return next(a for a in self.inputs if a.name == name)

    def output(self, name: str) -> Output:
        return next(o for o in self.outputs if o.name == name)

    def head_sizes(self) -> list[int]:
        """Per output, how many leading entries (row-major) :attr:`head` computes (0 without one)."""
        if self.head is None:
            return [0] * len(self.outputs)
        sizes = {o.name: o.size for o in self.head.outputs}
        return [sizes.get(o.name, 0) for o in self.outputs]

    def flat_outputs(self) -> list[sp.Expr]:
        """All output entries, output after output, row-major."""
        return [e for o in self.outputs for e in o.expr]

    def cse(self) -> tuple[list[tuple[sp.Symbol, sp.Expr]], list[list[sp.Expr]]]:
        """Common subexpressions across all outputs; reduced entries per output."""
        flat = self.flat_outputs()
        with sympy_speed.fast_factors():
            repl, reduced = csememo.cse(flat, optimizations="basic")
        out, k = [], 0
        for o in self.outputs:
            out.append(list(reduced[k : k + o.size]))
            k += o.size
        return list(repl), out
