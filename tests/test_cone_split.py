"""The split of dependent cones' tangential forces (``vcigen.cone_split.split``, C ``split`` in
``templates/sustained_cone_split.c.j2``): ``max_alpha min_c (cap_c - |F_c + alpha d_c|)``. Checked against a
dense scan of ``alpha`` (the margin is the maximum of a concave function: no scan point beats it), and the
bisection's early end (stop 34: it stops where the bracket no longer moves) against all ``SPLIT_ITER``
halvings, bit for bit."""

from __future__ import annotations

import math

import numpy as np
import pytest

from vcigen.cone_split import SPLIT_ITER, _term, split


def all_halvings(caps, forces, dirs):
    """The bisection of :func:`split` before stop 34: every one of the ``SPLIT_ITER`` halvings."""
    lo, hi = math.inf, -math.inf
    for force, d in zip(forces, dirs):
        dd = d[0] * d[0] + d[1] * d[1]
        if dd > 0.0:
            a = -(force[0] * d[0] + force[1] * d[1]) / dd
            lo, hi = min(lo, a), max(hi, a)
    if lo > hi:
        lo = hi = 0.0
    for _ in range(SPLIT_ITER):
        mid = 0.5 * (lo + hi)
        least, slope = math.inf, 0.0
        for cap, force, d in zip(caps, forces, dirs):
            value, s = _term(cap, force, d, mid)
            if value < least:
                least, slope = value, s
        if slope > 0.0:
            lo = mid
        else:
            hi = mid
    alpha = 0.5 * (lo + hi)
    values = [_term(cap, force, d, alpha)[0] for cap, force, d in zip(caps, forces, dirs)]
    return min(values), alpha, values


def random_cones(rng: np.random.Generator, n: int):
    caps = list(rng.uniform(0.0, 2.0, n))
    forces = [tuple(rng.normal(size=2)) for _ in range(n)]
    dirs = [tuple(rng.normal(size=2)) if rng.uniform() > 0.1 else (0.0, 0.0) for _ in range(n)]
    return caps, forces, dirs


@pytest.mark.parametrize("seed", range(200))
def test_the_split_ends_where_all_halvings_end_bit_for_bit(seed):
    rng = np.random.default_rng(seed)
    args = random_cones(rng, int(rng.integers(1, 5)))
    assert split(*args) == all_halvings(*args)


@pytest.mark.parametrize("seed", range(20))
def test_the_split_margin_is_the_best_over_alpha(seed):
    rng = np.random.default_rng(seed)
    caps, forces, dirs = random_cones(rng, 3)
    margin, alpha, values = split(caps, forces, dirs)
    assert margin == min(values)
    scan = np.linspace(alpha - 5.0, alpha + 5.0, 20001)
    best = max(min(_term(c, f, d, a)[0] for c, f, d in zip(caps, forces, dirs)) for a in scan)
    assert best <= margin + 1e-12
