"""Discrete Noether theorem (Thm 3.2): momenta of symmetries that leave the contacts invariant."""

import numpy as np
import pytest
from scenes import simulator

RULES = ["trapezoid", "midpoint"]


@pytest.mark.parametrize("rule", RULES)
@pytest.mark.parametrize(
    "scene,setup",
    [
        ("particle", {"q0": [0.0, 1.0], "v0": [-2.0, 0.0], "h": 0.01}),
        ("star", {"q0": [0.0, 3.5, 0.0], "v0": [-2.0, 0.0, 5.0], "h": 0.005}),
    ],
)
def test_horizontal_momentum_conserved_on_a_floor(scene, setup, rule):
    res = simulator(scene, rule).simulate(**setup, n_impacts=30)
    px = res.p[:, 0]
    assert np.max(np.abs(px - px[0])) < 1e-12 * max(1.0, abs(px[0]))
    assert res.n_impacts == 30


@pytest.mark.parametrize("rule", RULES)
def test_angular_momentum_conserved_in_circular_billiard(rule):
    res = simulator("billiard", rule).simulate(q0=[0.2, 0.0], v0=[0.3, 1.5], h=0.01, n_impacts=40)
    ang = res.q[:, 0] * res.p[:, 1] - res.q[:, 1] * res.p[:, 0]
    assert res.n_impacts == 40
    assert np.max(np.abs(ang - ang[0])) < 1e-12 * abs(ang[0])
    # The radial momentum really jumps at the rim: the test is not vacuous.
    assert min(im.impulse for im in res.impacts) > 0.1
