"""The line form of a row whose zero set is a quadratic's (vcigen.held.line_form).

One active row ``psi`` with ``psi = 0`` equivalent to ``F(q) = 0``, ``F`` a polynomial of degree 2 (a
circle's, a sphere's, an ellipse's, a rod's row): along the held step's line ``q1 = a + Lam b`` the row
vanishes where ``F(a + Lam b) = A Lam^2 + B Lam + C = 0``, which the closed step solves
(tests/test_held_closed.py, tests/test_held_quadric.py). Until stop 24 a row with a line form whose ``A``
and ``W`` varied (an ellipse's) kept the held Newton with a second start at that quadratic's root (the
line start); every such row now has the closed step, and the line start is gone.
"""

from __future__ import annotations

import numpy as np
import pytest
import sympy as sp

from vcigen import held

X, Y, Z = sp.symbols("x y z")
R = sp.Symbol("R", positive=True)


@pytest.mark.parametrize(
    ("psi", "curved"),
    [
        (R - sp.sqrt(X**2 + Y**2), True),  # inside a circle
        (sp.sqrt((X - 1) ** 2 + Y**2) - R, True),  # outside a circle about (1, 0)
        (3 - 2 * sp.sqrt(X**2 + 4 * Y**2 + Z**2), True),  # inside an ellipsoid
        (X**2 + Y**2 - 1, True),  # a rod
        (Y, False),  # linear: the previous multipliers solve it
        (Y + X / 3, False),
        (Y - sp.sin(X), False),
        (sp.sqrt(X) - 1, False),  # sqrt of a polynomial of degree 1: not a quadratic's zero set
        (X * Y + sp.sqrt(X**2 + Y**2), False),
        (X**3 + Y, False),
    ],
)
def test_line_form_has_the_rows_zero_set(psi: sp.Expr, curved: bool) -> None:
    """``F`` is a polynomial of degree 2 that vanishes where ``psi`` does (points on ``psi = 0``, found by
    bisection along rays) and not where ``psi`` is away from 0; ``None`` for the other forms."""
    q = (X, Y, Z)
    f = held.line_form(psi, q)
    assert (f is not None) == curved
    if f is None:
        return
    assert sp.Poly(sp.expand(f), *q).total_degree() == 2
    rng = np.random.default_rng(0)
    at = {R: 1.5}
    fpsi = sp.lambdify(q, psi.subs(at))
    ff = sp.lambdify(q, f.subs(at))
    hits = 0
    for _ in range(40):
        d = rng.normal(size=3)
        d /= np.linalg.norm(d)
        c = np.array([0.2, 0.1, 0.0]) if psi.has(X - 1) else np.zeros(3)
        lo, hi = 0.01, 10.0
        if np.sign(fpsi(*(c + lo * d))) == np.sign(fpsi(*(c + hi * d))):
            continue
        for _ in range(200):
            mid = 0.5 * (lo + hi)
            if np.sign(fpsi(*(c + mid * d))) == np.sign(fpsi(*(c + lo * d))):
                lo = mid
            else:
                hi = mid
        hits += 1
        assert abs(ff(*(c + lo * d))) <= 1e-12 * (1 + np.linalg.norm(c + lo * d) ** 2)
        far = c + 1.5 * lo * d  # psi clearly not 0 there
        assert abs(fpsi(*far)) > 1e-3 and abs(ff(*far)) > 1e-3
    assert hits >= 20
