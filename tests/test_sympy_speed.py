"""``vcigen.sympy_speed.fast_factors``: SymPy's ``Factors`` from a dict without the wasted comparison gives
the same factors, and the CSE of derived routines is the same expression for expression."""

from __future__ import annotations

from collections import defaultdict

import pytest
import sympy as sp
from sympy.core.exprtools import Factors
from test_memo import ball

from vcigen import sympy_speed
from vcigen.derive import derive

x, y = sp.symbols("x y", real=True)
DICTS = [
    {},
    {x: 2, y: -1},
    {sp.S.NegativeOne: 1, x: 3},
    {sp.I: 3, x: sp.Rational(1, 2)},
    {sp.S.One: 4, sp.S.NegativeOne: 2, y: x},
    {sp.Integer(2): 1, sp.Integer(3): -1},
    defaultdict(int, {x: 1, sp.S.NegativeOne: 3}),
]


@pytest.mark.parametrize("factors", DICTS, ids=range(len(DICTS)))
def test_factors_of_a_dict_are_sympys(factors) -> None:
    theirs = Factors(factors)
    with sympy_speed.fast_factors():
        checked = sp.__version__.startswith(sympy_speed.CHECKED)
        assert (Factors.__init__ is not sympy_speed.ORIGINAL) == checked
        ours = Factors(factors)
        other = Factors(x**2 * y)  # not a dict: SymPy's own
    assert Factors.__init__ is sympy_speed.ORIGINAL  # restored after the block
    assert ours.factors == theirs.factors and list(ours.factors) == list(theirs.factors)
    assert type(ours.factors) is type(theirs.factors) and ours.gens == theirs.gens
    assert other.factors == Factors(x**2 * y).factors


def test_the_cse_of_derived_routines_is_the_same() -> None:
    system = derive(ball(name="speed_ball"), "lobatto3", sensitivities=True)
    for name in ("smooth", "jump", "d_segment", "d_jump", "contact_time_floor"):
        flat = system.routines[name].flat_outputs()
        theirs = sp.cse(flat, symbols=sp.numbered_symbols("t", real=True), optimizations="basic")
        with sympy_speed.fast_factors():
            ours = sp.cse(flat, symbols=sp.numbered_symbols("t", real=True), optimizations="basic")
        assert sp.srepr(ours) == sp.srepr(theirs), name
