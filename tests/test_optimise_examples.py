"""The optimisation examples (``examples/optimise``) converge: Newton shooting quadratically through two
bounces, IPOPT to a throw whose replay with ``simulate`` strikes the wall at the prescribed point."""

import numpy as np
import pytest
from scenes import load_example


def test_shooting_converges_quadratically_to_the_launch_that_made_the_target():
    out = load_example("optimise/shooting").solve(fast=True, verbose=False)
    r = out["residuals"]
    assert r[-1] <= 1e-13, r
    # the last Newton steps are quadratic: r_{k+1} <= C r_k^2 once r_k is small (C ~ 10 measured)
    tail = [(a, b) for a, b in zip(r, r[1:]) if 1e-12 < a < 1e-3]
    assert len(tail) >= 2 and all(b <= max(100.0 * a * a, 1e-14) for a, b in tail), r
    # an independent check: the target came from simulate with V_TRUE, not from the composed Functions
    assert np.abs(out["v0"] - out["v_true"]).max() <= 1e-10, out["v0"]
    assert np.abs(out["replayed"] - out["target"]).max() <= 1e-12
    assert out["bounces"] == out["true_bounces"] == ["right", "bottom"]


@pytest.mark.parametrize("torque", [False, True], ids=["v0", "torque"])
def test_throw_is_solved_and_replayed_at_the_target(torque):
    """Decision variables the initial velocity, or constant joint torques from rest (forces, parameters)."""
    out = load_example("optimise/throw").solve(fast=True, verbose=False, torque=torque)
    assert out["success"], out["status"]
    assert out["impacts"] == 1 and out["impact_step"] == out["k_steps"]  # the mode sequence of the NLP
    assert np.abs(out["replayed"] - out["target"]).max() <= 1e-9, (out["replayed"], out["target"])
    assert 0.05 - 1e-7 <= out["alpha"] <= 0.95 + 1e-7 and out["impulse"] > 0  # IPOPT relaxes bounds by 1e-8
