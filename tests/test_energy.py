"""Energy: equal across every impact (48a); bounded, with no drift, over long runs (Figs. 2, 4)."""

import numpy as np
import pytest
from scenes import simulator

from vcigen.analysis import energy_drift

RULES = ["trapezoid", "midpoint"]
RUNS = {
    "particle": {"q0": [0.0, 1.0], "v0": [-2.0, 0.0], "h": 0.01},
    "star": {"q0": [0.0, 3.5, 0.0], "v0": [-2.0, 0.0, 5.0], "h": 0.005},
    "billiard": {"q0": [0.2, 0.0], "v0": [0.3, 1.5], "h": 0.01},
}


@pytest.mark.parametrize("rule", RULES)
@pytest.mark.parametrize("scene", sorted(RUNS))
def test_energy_equal_across_every_impact(scene, rule):
    res = simulator(scene, rule).simulate(**RUNS[scene], n_impacts=40)
    assert res.n_impacts == 40
    scale = abs(res.energy[0])
    jumps = np.array([im.energy_after - im.energy_before for im in res.impacts])
    assert np.max(np.abs(jumps)) <= 1e-11 * scale
    # The grid step holding the impact reports the energy carried through it.
    for im in res.impacts:
        assert res.energy[im.step] == pytest.approx(im.energy_before, rel=1e-12)
    assert all(im.impulse > 0 for im in res.impacts)


@pytest.mark.parametrize("rule", RULES)
def test_particle_energy_bounded_without_drift(rule):
    res = simulator("particle", rule).simulate(**RUNS["particle"], n_impacts=300)
    e0 = res.energy[0]
    assert res.max_energy_deviation() < 2e-3  # O(h^2) oscillation, paper Fig. 2
    span = res.t[-1] - res.t[0]
    assert abs(energy_drift(res)) * span < 2e-4  # no secular trend over ~270 s
    # Mean energy of the last tenth of the run equals that of the first tenth.
    k = res.energy.size // 10
    assert abs(res.energy[-k:].mean() - res.energy[:k].mean()) < 5e-4 * abs(e0)


def test_star_energy_bounded_over_many_impacts():
    res = simulator("star").simulate(**RUNS["star"], n_impacts=300)
    assert res.n_impacts == 300
    assert res.max_energy_deviation() < 1e-3
