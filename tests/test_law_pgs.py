"""The impulse law's complementarity problem by projected block Gauss-Seidel (``vcigen.law_pgs.pgs``,
stop 35), against the conditions that define its solution (MATH.md *Friction*: Coulomb's cone at an impact,
Newton's law on the normal rows), checked here independently on random rigid bodies with several rough
contacts: every normal impulse >= 0 with the normal velocity after at its target where it pushes and above it
where not, every cone's impulse inside it where the contact sticks (its sliding after 0) and on its edge
against its sliding after where it slides; a plastic impact loses kinetic energy."""

from __future__ import annotations

import math

import numpy as np
import pytest

from vcigen.law_pgs import pgs


def contact_problem(rng: np.random.Generator, k: int):
    """A body with six freedoms (random mass), ``k`` rough contacts (a normal row, two stick rows each, random
    gradients), approaching: ``(w, b, cones, mass, vel, g)`` for a plastic impact (targets 0)."""
    a = rng.normal(size=(6, 6))
    mass = a @ a.T + 6 * np.eye(6)
    g = rng.normal(size=(3 * k, 6))
    vel = rng.normal(size=6)
    for c in range(k):  # every normal row approaching
        g[3 * c] *= -math.copysign(1.0, float(g[3 * c] @ vel))
    w = g @ np.linalg.solve(mass, g.T)
    b = -g @ vel
    cones = [(3 * c, 3 * c + 1, 3 * c + 2, float(rng.uniform(0.2, 1.0))) for c in range(k)]
    return w, b, cones, mass, vel, g


@pytest.mark.parametrize("k", [1, 2, 3])
def test_the_projected_gauss_seidel_meets_coulomb_and_newton(k):
    rng = np.random.default_rng(100 + k)
    solved = sticks = slides = 0
    for _ in range(30):
        w, b, cones, mass, vel, g = contact_problem(rng, k)
        lam = pgs(w, b, cones, [], [])
        if lam is None:
            continue
        solved += 1
        gap = w @ lam - b  # velocities after, less their targets (0)
        scale = 1e-10 * (1.0 + np.abs(lam).max() + np.abs(b).max())
        for n, i, o, mu in cones:
            assert lam[n] >= -scale and gap[n] >= -scale and min(lam[n], gap[n]) <= scale
            t, u = math.hypot(lam[i], lam[o]), math.hypot(gap[i], gap[o])
            assert t <= mu * lam[n] + scale
            if u > scale:  # sliding after: on the cone's edge, against it
                slides += 1
                assert abs(t - mu * lam[n]) <= scale
                assert lam[i] * gap[i] + lam[o] * gap[o] <= -(1 - 1e-6) * t * u
            else:
                sticks += 1
        after = vel + np.linalg.solve(mass, g.T @ lam)
        assert after @ mass @ after <= vel @ mass @ vel * (1 + 1e-12)
    assert solved >= 25  # the sweeps settle on most
    assert sticks > 0 and slides > 0  # both kinds met


def test_the_projected_gauss_seidel_holds_bilateral_and_frictionless_rows():
    """A frictionless normal row (projected) and a bilateral row (at its target) beside a cone."""
    rng = np.random.default_rng(7)
    w, b, cones, mass, vel, g = contact_problem(rng, 2)
    cone, normal, equal = cones[:1], [3], [4]  # the second contact: frictionless normal, bilateral tangent
    lam = pgs(w, b, cone, normal, equal)
    assert lam is not None
    gap = w @ lam - b
    assert lam[5] == 0.0  # a row of none of them: no impulse
    assert abs(gap[4]) < 1e-12
    assert lam[3] >= 0 and gap[3] >= -1e-12 and min(lam[3], gap[3]) < 1e-12
