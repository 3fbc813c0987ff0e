"""A faster ``sympy.core.exprtools.Factors`` from a dict: the same result without a wasted comparison.

``sympy.cse(..., optimizations="basic")`` runs ``factor_terms`` on every expression, and ``factor_terms``
builds ``Factors`` from dicts hundreds of thousands of times. ``Factors.__init__`` first tests
``factors in (None, S.One)``: for a dict that calls ``Integer.__eq__``, which sympifies the whole dict into
a sorted ``sympy.Dict`` only to find it is not a number (SymPy 1.14). That comparison is always false for
a dict (the CSE of the double pendulum's routines under ``lobatto3``: 10.7 s -> 8.7 s without it).

Inside :func:`fast_factors` (around vcigen's CSE calls) ``Factors.__init__`` is one that takes a ``dict``
(or ``defaultdict``) straight to the original's dict branch (copied below) and hands every other argument
to the original: the same factors in the same order, so every ``cse`` result, generated file and CasADi
function is unchanged (``tests/test_sympy_speed.py`` compares both on derived routines). Only on the SymPy
versions it was checked on (:data:`CHECKED`); others keep SymPy's own, and so does SymPy outside those
blocks.
"""

from __future__ import annotations

import threading
from collections import defaultdict
from collections.abc import Iterator
from contextlib import contextmanager

import sympy
from sympy import I, S
from sympy.core.exprtools import Factors, _isnumber
from sympy.core.numbers import equal_valued

CHECKED = ("1.14.",)  # SymPy versions whose Factors.__init__ the dict branch below was copied from
ORIGINAL = Factors.__init__


def _from_dict(self: Factors, factors: dict) -> None:
    """``Factors.__init__``'s branch for a dict and its end (SymPy 1.14, ``sympy/core/exprtools.py``)."""
    factors = factors.copy()  # /!\ should be dict-like

    # tidy up -/+1 and I exponents if Rational

    handle = [k for k in factors if k is I or k in (-1, 1)]
    if handle:
        i1 = S.One
        for k in handle:
            if not _isnumber(factors[k]):
                continue
            i1 *= k ** factors.pop(k)
        if i1 is not S.One:
            for a in i1.args if i1.is_Mul else [i1]:  # at worst, -1.0*I*(-1)**e
                if a is S.NegativeOne:
                    factors[a] = S.One
                elif a is I:
                    factors[I] = S.One
                elif a.is_Pow:
                    factors[a.base] = factors.get(a.base, S.Zero) + a.exp
                elif equal_valued(a, 1):
                    factors[a] = S.One
                elif equal_valued(a, -1):
                    factors[-a] = S.One
                    factors[S.NegativeOne] = S.One
                else:
                    raise ValueError(f"unexpected factor in i1: {a}")

    self.factors = factors
    self.gens = frozenset(factors.keys())


def _init(self: Factors, factors=None) -> None:
    if type(factors) is dict or type(factors) is defaultdict:
        _from_dict(self, factors)
    else:
        ORIGINAL(self, factors)


_lock = threading.Lock()
_depth = 0  # fast_factors() blocks open (in any thread)


@contextmanager
def fast_factors() -> Iterator[None]:
    """The fast ``Factors.__init__`` in place while the block runs (on a checked SymPy), SymPy's own again
    after the last open block (nested and concurrent blocks are fine: both give the same factors)."""
    global _depth
    with _lock:
        _depth += 1
        if _depth == 1 and sympy.__version__.startswith(CHECKED):
            Factors.__init__ = _init
    try:
        yield
    finally:
        with _lock:
            _depth -= 1
            if _depth == 0:
                Factors.__init__ = ORIGINAL
