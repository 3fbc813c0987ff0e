"""Impacts a hair after or before a grid time, and a start exactly on the boundary."""

import math

import numpy as np
import pytest
from scenes import simulator

G, H = 9.81, 0.01


def drop_height(k: int, rel: float) -> float:
    """Height from which a particle at rest lands at t = k h (1 + rel) (exact parabola)."""
    return G * (k * H * (1 + rel)) ** 2 / 2


@pytest.mark.parametrize("backend", ["casadi", "c"])
@pytest.mark.parametrize("rule", ["trapezoid", "midpoint"])
def test_impact_at_the_end_or_start_of_a_step(rule, backend):
    sim = simulator("particle", rule, backend)
    finals = []
    for rel in (-1e-13, -1e-15, 0.0, 1e-15, 1e-13):
        y0 = drop_height(30, rel)
        res = sim.simulate(q0=[0.0, y0], v0=[0.0, 0.0], h=H, t_end=0.6)
        assert res.n_impacts == 1, "no lost or doubled impact"
        im = res.impacts[0]
        t_hit = math.sqrt(2 * y0 / G)
        assert im.t == pytest.approx(t_hit, abs=1e-12)
        assert min(im.alpha, 1 - im.alpha) < 1e-9  # the impact sits on a grid time
        assert im.energy_after == pytest.approx(im.energy_before, abs=1e-12)
        assert np.all(res.q[:, 1] >= -1e-9)
        t = res.t[-1] - t_hit
        assert abs(res.q[-1, 1] - (G * t_hit * t - G * t * t / 2)) < G * H**2  # O(h^2)
        finals.append(np.concatenate([res.q[-1], res.p[-1]]))
    # alpha -> 1 in step k-1 and alpha -> 0 in step k give the same trajectory.
    spread = np.max(np.ptp(np.array(finals), axis=0))
    assert spread < 1e-9, spread


@pytest.mark.parametrize("backend", ["casadi", "c"])
def test_start_exactly_on_the_boundary_moving_in(backend):
    res = simulator("particle", "trapezoid", backend).simulate(q0=[0.0, 0.0], v0=[1.0, -3.0], h=H, t_end=0.1)
    assert res.n_impacts == 1
    im = res.impacts[0]
    assert im.t == pytest.approx(0.0, abs=1e-12) and im.step == 0
    # The normal velocity reverses, up to the O(h^2) bias of E_d over the step: g^2 h^2 / (8 v_n).
    assert abs(im.impulse - 6.0) < 2 * G**2 * H**2 / 8 / 3.0 * 2
    assert np.all(res.q[:, 1] >= -1e-12)


def test_start_exactly_on_the_boundary_moving_out():
    res = simulator("particle").simulate(q0=[0.0, 0.0], v0=[1.0, 3.0], h=H, t_end=0.1)
    assert res.n_impacts == 0 and res.q[1, 1] > 0
