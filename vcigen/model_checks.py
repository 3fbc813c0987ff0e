"""Numeric checks of a model's expressions where a symbolic proof costs too much (:class:`vcigen.Model`)."""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np
import sympy as sp

SAMPLES = 8  # random configurations a dependence is tested at
SEED = 20261207  # fixed: a model is accepted or refused the same way every time
# the normalised Gram determinant below which gradients are dependent (of two: the sin^2 of their angle)
INDEPENDENT = 1e-12


def dependent_everywhere(
    exprs: Sequence[sp.Expr], coords: Sequence[sp.Symbol], params: Mapping[sp.Symbol, float]
) -> bool:
    """Are the gradients of ``exprs`` in ``coords`` linearly dependent at every one of ``SAMPLES`` random
    configurations (``q`` uniform in [-2, 2], the parameters at their values) where they are finite and not
    0? The Gram determinant of the normalised gradients is the squared volume they span: 0 where dependent,
    1 where orthogonal. False where fewer than three samples are finite (nothing to say)."""
    grads = sp.Matrix([[sp.diff(e, c) for c in coords] for e in exprs])
    values = [float(params[s]) for s in params]
    fn = sp.lambdify([list(coords), list(params)], grads, modules="numpy")
    rng = np.random.default_rng(SEED)
    seen = 0
    for _ in range(SAMPLES):
        q = rng.uniform(-2.0, 2.0, len(coords))
        with np.errstate(all="ignore"):
            try:
                g = np.array(fn(q, values), dtype=float)
            except (ZeroDivisionError, ValueError, TypeError, OverflowError, NameError):
                continue
        norms = np.linalg.norm(g, axis=1)
        if not np.isfinite(g).all() or not (norms > 0).all():
            continue
        unit = g / norms[:, None]
        seen += 1
        if np.linalg.det(unit @ unit.T) > INDEPENDENT:
            return False
    return seen >= 3
