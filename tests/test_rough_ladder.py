"""A ladder between a rough floor and a rough wall (MATH.md *Friction*): two one-tangent contacts whose stick
rows hold the same freedom.

With both normal rows held the ladder (a uniform rod, unit mass and length, angle ``th`` from the wall) turns
about the corner; both stick rows hold that one turn, so the wall's is dependent and rides on the floor's
(``FrictionModes._stick``). Its tangential forces are not unique: the floor's friction can hold the ladder
alone, or the wall's can share it, which lifts the ladder off the floor (the null combination has a part on
the normal rows). Statics: it stands while ``tan th <= 2 mu / (1 - mu^2)``, both contacts at the edge of their
cones at the limit. Till stop 46 the riding wall's cone was *pooled* into the floor's, ``mu (N_floor +
N_wall) >= |F_floor|`` with the normal forces of the floor holding alone: the ladder stood at every angle
tried (up to 0.02 rad past the limit), a silent wrong trajectory. The cone now takes the best split along
the null combination with the normal forces shifted (``FrictionModes._stick_split``, C ``stick_split``,
:func:`vcigen.cone_split.split_line`). Sliding, both ends slip; the reference is scipy's ODE of the rod with
kinetic friction at both ends (``N_floor``, ``N_wall`` and ``th''`` solved at each state) and the wall's
release where ``N_wall = 0``."""

from __future__ import annotations

import math
from functools import cache

import numpy as np
import pytest
import test_sustained_closed_forms
from hard_scenes import BACKENDS, G
from scipy.integrate import solve_ivp

import vcigen
from vcigen.analysis import fit_order


def model() -> vcigen.Model:
    """The ladder of ``test_sustained_closed_forms``, rough at both ends (``mu``)."""
    return test_sustained_closed_forms.ladder(rough=True)


@cache
def ladder(backend: str) -> vcigen.Simulator:
    return vcigen.build(model(), backend=backend)


def limit(mu: float) -> float:
    """The steepest standing angle: ``tan th = 2 mu / (1 - mu^2)``."""
    return math.atan(2 * mu / (1 - mu * mu))


def run(backend: str, mu: float, th0: float, h: float, t_end: float) -> vcigen.Result:
    q0 = [math.sin(th0) / 2, math.cos(th0) / 2, th0]
    return ladder(backend).simulate(q0=q0, v0=[0.0, 0.0, 0.0], h=h, t_end=t_end, params={"mu": mu})


def sliding(mu: float, th: float, w: float) -> tuple[float, float, float]:
    """``(th'', N_floor, N_wall)`` of the ladder sliding down (its foot away from the wall, its top down) with
    kinetic friction ``mu N`` at both ends: the centre's two equations and the turn about it."""
    s, c = math.sin(th), math.cos(th)
    a = np.array([[c / 2, mu, -1.0], [-s / 2, -1.0, -mu], [1 / 12, -(s - mu * c) / 2, (mu * s + c) / 2]])
    acc, n_floor, n_wall = np.linalg.solve(a, [s * w * w / 2, -G + c * w * w / 2, 0.0])
    return float(acc), float(n_floor), float(n_wall)


def reference(mu: float, th0: float):
    """scipy (DOP853, tolerances 1e-12) from rest to the wall's release: ``(t_release, dense th(t))``."""

    def release(t, s):
        return sliding(mu, s[0], s[1])[2]

    release.terminal, release.direction = True, -1
    sol = solve_ivp(
        lambda t, s: [s[1], sliding(mu, s[0], s[1])[0]],
        (0.0, 2.0),
        [th0, 0.0],
        method="DOP853",
        rtol=1e-12,
        atol=1e-12,
        events=release,
        dense_output=True,
    )
    return float(sol.t_events[0][0]), sol.sol


@pytest.mark.parametrize("mu", [0.3, 0.6])
@pytest.mark.parametrize("backend", BACKENDS)
def test_a_rough_ladder_stands_below_its_friction_angle_and_slides_above_it(backend, mu):
    """0.002 rad below the limit it stands for a second, both ends held; 0.002 rad above it slides (it stood
    before: the pooled cone had room for the floor's force alone)."""
    below = run(backend, mu, limit(mu) - 0.002, 0.01, 1.0)
    assert np.abs(below.q - below.q[0]).max() < 1e-12 and below.active.all() and not below.impacts
    above = run(backend, mu, limit(mu) + 0.002, 0.01, 1.0)
    assert above.q[-1, 2] - above.q[0, 2] > 0.05 and above.active[:, 0].all()


@pytest.mark.parametrize(("mu", "past"), [(0.3, 0.02), (0.6, 0.02), (0.3, 0.2)])
@pytest.mark.parametrize("backend", BACKENDS)
def test_a_rough_ladder_slides_on_both_ends_as_scipy_to_order_two(backend, mu, past):
    """Released ``past`` the limit, it slides with both ends slipping; its angle, both normal forces (at each
    step's mean angle and rate) and the wall's release time converge at order 2 to scipy's. Measured (both
    backends alike, h = 0.01 to 0.0025): the release time within 0.361 h^2, the angle within 1.33 h^2, the
    forces within 6.9-19.9 h^2 (the constant still rising by half its last rise as h halves: the forces change
    fastest at the release)."""
    t_release, th_ref = reference(mu, limit(mu) + past)
    hs, errs = [0.01, 0.005, 0.0025], []
    for h in hs:
        res = run(backend, mu, limit(mu) + past, h, 1.2)
        assert [j for _, j in res.liftoffs][:1] == ["wall"]
        t_lift = res.liftoffs[0][0]
        errs.append(abs(t_lift - t_release))
        assert errs[-1] <= 0.4 * h * h, (h, errs[-1] / h**2)
        held = int(t_lift // h)
        assert res.active[: held + 1].all()
        assert np.abs(res.q[:held, 2] - th_ref(res.t[:held])[0]).max() <= 1.4 * h * h
        mid = th_ref(res.t[1 : held - 1] + h / 2)
        exact = np.array([sliding(mu, th, w)[1:] for th, w in mid.T])
        assert np.abs(res.contact_force[1 : held - 1] - exact).max() <= 25 * h * h
    assert 1.9 < fit_order(hs, errs) < 2.1, errs
