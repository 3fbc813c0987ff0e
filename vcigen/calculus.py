"""Jacobians and Hessians that differentiate an entry only in the symbols it holds.

The residuals of a scene with many bodies and contacts are sparse: a contact's row holds a
few coordinates, a body's momentum row a few velocities. ``sp.Matrix.jacobian`` and
``sp.hessian`` differentiate every entry in every symbol (``O(rows x cols)`` derivatives of
whole expressions, ``O(n^3)`` for the mass matrix of a sum over n bodies); these skip the
pairs whose derivative is 0 and give the same expressions otherwise (MATH.md: exact Jacobians).
"""

from __future__ import annotations

from collections.abc import Sequence

import sympy as sp


def _no_dirac(e: sp.Expr) -> sp.Expr:
    return e.replace(lambda x: isinstance(x, sp.DiracDelta), lambda x: sp.S.Zero)


def jacobian(res: sp.Matrix, xs: Sequence[sp.Symbol], drop_dirac: bool = True) -> sp.Matrix:
    """``d res / d xs`` (``res.jacobian(xs)``), differentiating each entry only in the symbols it holds.

    A ``sign()`` in a residual (a stick row's tangent) leaves a Dirac mass, which is no force: it is
    dropped unless ``drop_dirac`` is false.
    """
    rows = []
    for e in res:
        held = e.free_symbols
        row = [e.diff(x) if x in held else sp.S.Zero for x in xs]
        rows.append([_no_dirac(d) if drop_dirac and d.has(sp.DiracDelta) else d for d in row])
    return sp.Matrix(res.rows * res.cols, len(xs), [d for row in rows for d in row])


def hessian(f: sp.Expr, xs: Sequence[sp.Symbol]) -> sp.Matrix:
    """``sp.hessian(f, xs)``: the upper triangle ``f.diff(x_i).diff(x_j)`` mirrored, zeros skipped."""
    n = len(xs)
    out = [[sp.S.Zero] * n for _ in range(n)]
    for i, xi in enumerate(xs):
        if xi not in f.free_symbols:
            continue
        di = f.diff(xi)
        held = di.free_symbols
        for j in range(i, n):
            if xs[j] in held:
                out[i][j] = out[j][i] = di.diff(xs[j])
    return sp.Matrix(out)
