"""The pure parts of the impulse law's loose landing cones (MATH.md *Friction*, stop 33), against NumPy's
independent references: the least split of a dependent set of tight rows (``impulse_law._least_split``)
is the minimum-norm solution of ``W_TT Lam = b_T`` (``numpy.linalg.lstsq``); Coulomb's slide along a line
(``friction.line_slide``) is against the velocity after and on the cone's edge; the energy test
(``impulse_law._gains``) is the kinetic energy's change."""

from __future__ import annotations

import numpy as np
import pytest

from vcigen.friction import line_slide
from vcigen.impulse_law import _gains, _least_split


def dependent_rows(rng: np.random.Generator, n: int = 5, r: int = 8, rank: int = 4) -> np.ndarray:
    """``r`` row gradients in ``R^n`` spanning ``rank`` directions."""
    return rng.normal(size=(r, rank)) @ rng.normal(size=(rank, n))


@pytest.mark.parametrize("seed", range(5))
def test_the_least_split_is_the_minimum_norm_impulse(seed):
    rng = np.random.default_rng(seed)
    g = dependent_rows(rng)
    a = rng.normal(size=(5, 5))
    mass = a @ a.T + 5 * np.eye(5)
    w = g @ np.linalg.solve(mass, g.T)
    b = g @ rng.normal(size=5)  # consistent targets: the rows' velocities of some velocity change
    tight = [0, 1, 2, 4, 5, 6, 7]
    lam = _least_split(g, w, b, tight)
    ref = np.linalg.lstsq(w[np.ix_(tight, tight)], b[tight], rcond=None)[0]
    # its normal equations (A^T A) z cost cond(A)^2 of round-off, A = G_T G_I^T (I: rows 0, 1, 2, 4)
    bound = 1e-14 * np.linalg.cond(g[tight] @ g[[0, 1, 2, 4]].T) ** 2
    assert np.abs(lam[tight] - ref).max() < bound * np.abs(ref).max()
    assert lam[3] == 0.0
    assert np.abs(w[np.ix_(tight, tight)] @ lam[tight] - b[tight]).max() < bound * np.abs(b).max()


def test_a_slide_along_a_line_opposes_the_sliding_after_on_the_cones_edge():
    u = np.array([0.6, 0.8])
    kappa, mu, a = 2.0, 0.4, 1.5
    h = kappa * np.outer(u, u)
    bn = np.array([0.1, -0.3])
    g = 3.0 * u  # the sliding before, along u
    m = np.array(line_slide(g, h.ravel(), bn, mu, a))
    normal = a - bn @ m
    after = g + h @ m
    assert abs(np.linalg.norm(m) - mu * normal) < 1e-14  # on the edge
    assert after @ u > 0 and abs(after @ np.array([-u[1], u[0]])) < 1e-14  # still along u
    assert np.allclose(m / np.linalg.norm(m), -u)  # against it
    assert line_slide(0.1 * u, h.ravel(), bn, mu, a) is None  # too slow: it sticks along u
    assert line_slide(g + [0.1, -0.075], h.ravel(), bn, mu, a) is None  # sliding across u: not a line


def test_the_energy_test_is_the_kinetic_energys_change():
    rng = np.random.default_rng(3)
    g = rng.normal(size=(3, 4))
    mass = np.diag([1.0, 2.0, 0.5, 3.0])
    vel = rng.normal(size=4)
    for lam in (rng.normal(size=3), -rng.normal(size=3)):
        after = vel + np.linalg.solve(mass, g.T @ lam)
        change = (after @ mass @ after - vel @ mass @ vel) / 2
        w = g @ np.linalg.solve(mass, g.T)
        tgts = rng.normal(size=3)
        b = tgts - g @ vel
        gap = w @ lam - b
        assert _gains(lam, b, gap, tgts) == (change > 0)
