"""Pure parts of the impulse law while held (MATH.md *Friction*), against independent references: the least
split of a dependent set of tight rows (``impulse_law._least_split``, stop 33) is the minimum-norm solution
of ``W_TT Lam = b_T`` (``numpy.linalg.lstsq``); Coulomb's slide along a line (``friction.line_slide``) is
against the velocity after and on the cone's edge; the energy test (``impulse_law._gains``) is the kinetic
energy's change; cones slipping at once (``ImpulseLaw._law_slide``'s block Gauss-Seidel, stop 32) end each on
its cone's edge against its sliding after, and sweeps that do not settle say so; a cone sliding while the
tight rows are dependent (stop 34) takes the least split of the rest (``lstsq``)."""

from __future__ import annotations

import numpy as np
import pytest

from vcigen import impulse_law
from vcigen.friction import line_slide
from vcigen.impulse_law import ImpulseLaw, _gains, _least_split


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


@pytest.mark.parametrize("seed", [1, 6, 8, 14, 15, 18])
def test_cones_slipping_at_once_end_on_their_edges_against_their_sliding(seed, monkeypatch):
    """Two isotropic cones (stick rows 2, 3 and 4, 5) coupled through random rows, their normal rows 0 and 1
    tight and plastic: after the sweeps each cone's tangential impulse is ``mu`` times its normal impulse and
    points against its tangential velocity after (Coulomb's sliding), the normal rows at rest. With one sweep
    allowed they cannot settle (the second sweep is the one that shows no move): ``(None, why)``."""
    rng = np.random.default_rng(seed)
    g = rng.normal(size=(6, 6))
    w = g @ g.T
    b = -g @ (3 * rng.normal(size=6))  # the rows' velocities before, negated (targets 0)
    slide = [(2, 3, [0], 0.3, 1, 0), (4, 5, [1], 0.3, 1, 2)]
    lam, why, line = ImpulseLaw._law_slide(None, slide, w, w, b, [0, 1], [], [], 1e-14)
    assert lam is not None and why == "" and not line
    gap = w @ lam - b  # the velocities after
    assert np.abs(gap[:2]).max() < 1e-13
    for i, o, normals, mu, _, _ in slide:
        m, after = np.array([lam[i], lam[o]]), np.array([gap[i], gap[o]])
        assert abs(np.linalg.norm(m) - mu * lam[normals[0]]) < 1e-12 * (1 + np.linalg.norm(m))
        assert m @ after / (np.linalg.norm(m) * np.linalg.norm(after)) < -1 + 1e-12
    monkeypatch.setattr(impulse_law, "SLIDE_SWEEPS", 1)
    lam, why, _ = ImpulseLaw._law_slide(None, slide, w, w, b, [0, 1], [], [], 1e-14)
    assert lam is None and "did not settle in 1 sweeps" in why


@pytest.mark.parametrize("seed", [0, 1, 3, 4, 5])
def test_a_cone_sliding_beside_dependent_tight_rows_takes_the_least_split_of_the_rest(seed):
    """A loose landing cone sliding (stick rows 5, 6, its normal row 0) while the tight rows 0-4 are dependent
    (a box landing flat, one vertex sliding, the others sticking): their impulses are not unique, so
    ``_law_slide`` takes each column's least split (``least``: the rows' gradients, stop 34). The tight rows
    meet their targets, the cone slides on its edge against its velocity after, and the tight rows' impulses
    are the minimum-norm solution of ``W_TT Lam_T = b_T - W_Tc m`` (``lstsq``), ``m`` the cone's impulse."""
    rng = np.random.default_rng(seed)
    g = rng.normal(size=(7, 6))
    g[4] = rng.normal(size=4) @ g[:4]  # the tight rows 0-4 span four directions
    a = rng.normal(size=(6, 6))
    w = g @ np.linalg.solve(a @ a.T + 6 * np.eye(6), g.T)
    b = -g @ (3 * rng.normal(size=6))  # the rows' velocities before, negated (targets 0): consistent
    tight, slide, mu = [0, 1, 2, 3, 4], [(5, 6, [0], 0.3, 1, 0)], 0.3
    lam, why, line = ImpulseLaw._law_slide(None, slide, w, w, b, tight, [], [], 1e-14, (), g)
    assert lam is not None and why == "" and not line
    gap = w @ lam - b  # the velocities after
    assert np.abs(gap[tight]).max() < 1e-11 * np.abs(b).max()
    m, after = lam[[5, 6]], gap[[5, 6]]
    assert lam[0] > 0 and abs(np.linalg.norm(m) - mu * lam[0]) < 1e-12 * np.linalg.norm(m)
    assert m @ after / (np.linalg.norm(m) * np.linalg.norm(after)) < -1 + 1e-12
    ref = np.linalg.lstsq(w[np.ix_(tight, tight)], b[tight] - w[np.ix_(tight, [5, 6])] @ m, rcond=None)[0]
    bound = 1e-14 * np.linalg.cond(g[tight] @ g[:4].T) ** 2
    assert np.abs(lam[tight] - ref).max() < bound * np.abs(ref).max()
