"""Splits of an impulse law's impulses over dependent rows (``vcigen.law_split``), against independent
references: the least split meets its rows' targets to the round-off of one solve, not of its normal equations
(its refinement, stop 35); ``fit`` finds a split inside the cones where one exists (one built by hand), with
the same generalized impulse, and says none where the cones cannot hold it (the sum of two cones at one
point)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from vcigen.law_split import fit, least_split


def graded_rows(rng: np.random.Generator, spread: float) -> np.ndarray:
    """Eight row gradients in ``R^5`` spanning four directions, their singular values from 1 down to
    ``spread``."""
    u = np.linalg.qr(rng.normal(size=(8, 4)))[0]
    v = np.linalg.qr(rng.normal(size=(5, 4)))[0]
    return u @ np.diag(np.geomspace(1.0, spread, 4)) @ v.T


@pytest.mark.parametrize("seed", range(6))
def test_the_least_split_meets_its_targets_past_its_normal_equations_round_off(seed):
    """Rows whose ``A = G_T G_I^T`` has ``cond(A)`` 1e4 to 4e4: the normal equations ``(A^T A) z`` alone
    miss the targets ``W_TT Lam = b_T`` by 5e-11 to 2e-9 of ``|b|`` on these six (``cond(A)^2`` of
    round-off); with the refinement step by at most 7e-14. It stays the minimum-norm impulse
    (``numpy.linalg.lstsq``)."""
    rng = np.random.default_rng(seed)
    g = graded_rows(rng, 1e-2)
    mass = np.diag(rng.uniform(1.0, 2.0, 5))
    w = g @ np.linalg.solve(mass, g.T)
    b = g @ rng.normal(size=5)  # consistent targets: the rows' velocities of some velocity change
    tight = list(range(8))
    lam = least_split(g, w, b, tight)
    cond = np.linalg.cond(g[tight] @ g[:4].T)  # rows 0-3: independent (random rows of rank 4)
    assert cond > 1e4
    assert np.abs(w @ lam - b).max() < 1e-12 * np.abs(b).max()
    ref = np.linalg.lstsq(w, b, rcond=None)[0]
    assert np.abs(lam - ref).max() < 1e-14 * cond**2 * np.abs(ref).max()


def three_cones(rng: np.random.Generator) -> tuple[np.ndarray, list, np.ndarray]:
    """Three cones (a normal row and two stick rows each) on a body with six freedoms (random rows: the nine
    are dependent, three null combinations), ``mu`` in [0.3, 0.8], and a split inside them with room."""
    g = rng.normal(size=(9, 6))
    cones, lam = [], np.zeros(9)
    for c in range(3):
        mu, n = rng.uniform(0.3, 0.8), rng.uniform(1.0, 2.0)
        t = rng.normal(size=2)
        lam[3 * c : 3 * c + 3] = n, *(t / np.linalg.norm(t) * rng.uniform(0.2, 0.7) * mu * n)
        cones.append((3 * c, 3 * c + 1, 3 * c + 2, mu))
    return g, cones, lam


def inside(lam, cones, eps) -> bool:
    return all(math.hypot(lam[i], lam[o]) <= mu * lam[n] + eps for n, i, o, mu in cones)


@pytest.mark.parametrize("seed", range(20))
def test_fit_finds_a_split_inside_the_cones_with_the_same_generalized_impulse(seed):
    rng = np.random.default_rng(seed)
    g, cones, lam_in = three_cones(rng)
    impulse = g.T @ lam_in  # what the law fixes; the split is free along the three null combinations
    start = np.linalg.lstsq(g.T, impulse, rcond=None)[0]  # the least split: often out of a cone
    out = fit(g, start, list(range(9)), cones, [], 1e-12)
    assert out is not None
    assert inside(out, cones, 1e-12)
    assert np.abs(g.T @ out - impulse).max() < 1e-12 * np.abs(impulse).max()


def test_fit_starts_out_of_a_cone_in_most_of_these():
    """The cases above are a test of ``fit``: the least split leaves a cone in most of them."""
    outside = 0
    for seed in range(20):
        g, cones, lam_in = three_cones(np.random.default_rng(seed))
        start = np.linalg.lstsq(g.T, g.T @ lam_in, rcond=None)[0]
        outside += not inside(start, cones, 1e-12)
    assert outside >= 10


@pytest.mark.parametrize("excess", [0.9, 1.2])
def test_fit_says_none_where_the_cones_cannot_hold_the_impulse(excess):
    """Two contacts at one point of a particle (normal ``z``, tangents ``x``, ``y``): any split has ``t1 +
    t2 = P_t``, ``n1 + n2 = P_z``, so one inside both cones exists if and only if ``|P_t| <= mu P_z``. From
    a split with one contact carrying all the tangential impulse (out of its cone) ``fit`` moves it across
    at 0.9 and finds none at 1.2."""
    mu = 0.5
    e = np.eye(3)
    g = np.array([e[2], e[0], e[1], e[2], e[0], e[1]])
    cones = [(0, 1, 2, mu), (3, 4, 5, mu)]
    pt = excess * mu * 2.0 * np.array([0.6, 0.8])
    start = np.array([1.0, *pt, 1.0, 0.0, 0.0])  # P_z = 2
    out = fit(g, start, list(range(6)), cones, [], 1e-12)
    if excess < 1.0:
        assert out is not None and inside(out, cones, 1e-12)
        assert np.abs(g.T @ out - g.T @ start).max() < 1e-12
    else:
        assert out is None
